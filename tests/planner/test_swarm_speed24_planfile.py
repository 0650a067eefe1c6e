"""Stop 62 round 24A: plan.json written compactly by json's C encoder (``PLAN_JSON_SEPARATORS``) and
``jsonable`` handing finite numeric arrays over as ``tolist()``: the same mapping as before, and a
plan written indented (the layout before) reads the same."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from proxplan.planfile import PLAN_FORMAT_VERSION, read_plan, write_plan
from proxplan.planfile.plan import PLAN_FILENAME, jsonable, plan_to_dict


def _jsonable_by_element(value: Any) -> Any:
    """The definition element by element (jsonable before round 24A): arrays through tolist, then
    every float checked for finiteness."""
    if isinstance(value, dict):
        return {str(k): _jsonable_by_element(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable_by_element(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable_by_element(value.tolist())
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def test_jsonable_gives_what_the_element_wise_definition_gives():
    rng = np.random.default_rng(3)
    with_nan = rng.normal(size=(4, 3))
    with_nan[1, 2] = np.nan
    with_nan[3, 0] = -np.inf
    doc = {
        "finite": rng.normal(size=(5, 3)),
        "float32": rng.normal(size=7).astype(np.float32),
        "with_nan": with_nan,
        "ints": np.arange(6, dtype=np.int64).reshape(2, 3),
        "bools": np.array([True, False, True]),
        "scalars": [np.float64(1.5), np.int32(4), np.bool_(True), float("nan"), "text", None],
        7: (np.zeros(0), np.zeros((0, 3))),
    }
    got, want = jsonable(doc), _jsonable_by_element(doc)
    assert got == want
    assert json.dumps(got) == json.dumps(want)  # the same text: same types, same values, NaN -> null
    assert got["with_nan"][1][2] is None and got["with_nan"][3][0] is None


def test_compact_plan_file_reads_as_the_plan_and_an_indented_one_still_reads(battery_swap_plan, tmp_path):
    plan = read_plan(battery_swap_plan)
    write_plan(plan, tmp_path / "compact")
    text = (tmp_path / "compact" / PLAN_FILENAME).read_text()
    assert "\n" not in text and text.startswith(f'{{"format_version":{PLAN_FORMAT_VERSION},')  # compact: the C encoder
    assert json.loads(text) == _jsonable_by_element(plan_to_dict(plan))
    (tmp_path / "indented").mkdir()
    (tmp_path / "indented" / PLAN_FILENAME).write_text(json.dumps(json.loads(text), indent=1))
    a, b = read_plan(tmp_path / "compact"), read_plan(tmp_path / "indented")
    assert set(a.vehicles) == set(b.vehicles) == set(plan.vehicles)
    for name, tr in plan.vehicles.items():
        for field in ("t_s", "position_m", "velocity_mps", "acceleration_mps2"):
            assert np.array_equal(getattr(a.vehicles[name], field), getattr(b.vehicles[name], field))
            assert np.array_equal(getattr(a.vehicles[name], field), np.round(getattr(tr, field), 6))
    assert a.metrics == b.metrics and a.scenario_spec == b.scenario_spec
