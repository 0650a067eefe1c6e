"""The formation-change generator: valid scenarios, distinct slots, every vehicle changes layer."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import formation_change, main


@pytest.mark.parametrize("n", [1, 2, 7, 32, 128])
def test_formations_are_valid_scenarios_with_distinct_slots(n):
    scenario = scenario_from_dict(formation_change(n))
    assert len(scenario.vehicles) == n
    starts = np.array([t.start_m for t in scenario.vehicles.values()])
    goals = np.array([t.goal_m for t in scenario.vehicles.values()])
    for points in (starts, goals):
        d = np.linalg.norm(points[:, None] - points[None], axis=2) + np.eye(n) * 1e9
        assert d.min() > 0.4  # slots far enough apart for any pair of the types used
    assert np.all(starts[:, 0] < 0) and np.all(goals[:, 0] > 0)  # west to east of the pillar
    assert np.all(starts[:, 2] != goals[:, 2])  # each vehicle changes layer


def test_generator_cli(tmp_path, capsys):
    assert main(["4", "--out", str(tmp_path / "f.yaml")]) == 0
    from proxplan.planfile import load_scenario

    assert len(load_scenario(tmp_path / "f.yaml").vehicles) == 4
    assert main(["0", "--out", str(tmp_path / "g.yaml")]) == 2
    assert "N: expected a whole number from 1 to" in capsys.readouterr().err
    assert main(["10000", "--out", str(tmp_path / "h.yaml")]) == 2  # beyond the planner's swarm limit
    assert "got 10000" in capsys.readouterr().err
    assert not (tmp_path / "h.yaml").exists()
