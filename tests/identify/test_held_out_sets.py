"""The held-out-sets benchmark's grouping and manifests, on a synthetic manifest without flight data
(benchmarks/bench_held_out_sets.py; docs/identify.md, "Stop 73, round 35O"). No identify run."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import bench_held_out_sets as bench  # noqa: E402

from proxplan.identify import load_manifest  # noqa: E402


def _flight(name: str, split: str, set_name: str | None = None) -> dict[str, Any]:
    f: dict[str, Any] = {"name": name, "split": split}
    if set_name:
        f["set"] = set_name
    f["vehicles"] = {"cf1": {"type": "crazyflie-2.1", "log": f"{name}/cf1.csv.gz"}}
    return f


def _doc() -> dict[str, Any]:
    return {
        "format": "neural-swarm",
        "root": "../data",
        "flights": [
            _flight("swap_ab_00", "train"),
            _flight("swap_ab_01", "train"),
            _flight("swap_ab_08", "test"),
            _flight("swap_abc_00", "train"),
            _flight("swap_abc_05", "test"),
            _flight("day23_swap_abc_00", "validation"),
            _flight("day23_swap_abc_02", "test"),
            _flight("day30_swap_zz_00", "test"),  # a day prefix with no same-order set: a group of its own
            _flight("takeoff_s_cf50", "train", "takeoff_s"),  # explicit set keys (the shipped take-offs)
            _flight("takeoff_s_cf51", "test", "takeoff_s"),
            _flight("takeoff_l_cf102", "train", "takeoff_l"),  # no test flight
        ],
    }


def test_groups_follow_the_set_rule_and_the_day_twin() -> None:
    groups = {g.name: g for g in bench.groups_of(_doc())}
    assert list(groups) == ["swap_ab", "swap_abc", "day30_swap_zz", "takeoff_s", "takeoff_l"]
    abc = groups["swap_abc"]
    assert abc.sets == ("swap_abc", "day23_swap_abc")
    assert abc.fit_flights == ("swap_abc_00", "day23_swap_abc_00")
    assert abc.test_flights == ("swap_abc_05", "day23_swap_abc_02")
    assert groups["swap_ab"].fit_flights == ("swap_ab_00", "swap_ab_01")
    assert groups["day30_swap_zz"].fit_flights == () and groups["day30_swap_zz"].test_flights == ("day30_swap_zz_00",)
    assert groups["takeoff_s"].test_flights == ("takeoff_s_cf51",)
    assert groups["takeoff_l"].test_flights == ()


def test_held_out_and_test_manifests_are_valid_and_keep_only_what_they_should(tmp_path: Path) -> None:
    doc = _doc()
    manifest = tmp_path / "manifests" / "m.yaml"
    manifest.parent.mkdir()
    (tmp_path / "data").mkdir()
    root = bench.absolute_root(doc, manifest)
    assert Path(root).is_absolute() and Path(root) == (tmp_path / "data").resolve()
    abc = next(g for g in bench.groups_of(doc) if g.name == "swap_abc")

    held = bench.held_out_manifest(doc, abc, root)
    names = [f["name"] for f in held["flights"]]
    assert not set(abc.fit_flights) & set(names)
    assert set(abc.test_flights) <= set(names)
    assert len(names) == len(doc["flights"]) - len(abc.fit_flights)
    assert doc["root"] == "../data" and len(doc["flights"]) == 11  # the shipped document is not changed

    elsewhere = tmp_path / "elsewhere"  # an absolute root: the written manifest reads from anywhere
    elsewhere.mkdir()
    path = elsewhere / "held.yaml"
    path.write_text(yaml.safe_dump(held, sort_keys=False))
    loaded = load_manifest(path)
    assert {f.name for f in loaded.flights if f.split == "test"} >= set(abc.test_flights)
    assert not any(f.split == "validation" for f in loaded.flights)  # the only validation flight was abc's

    tman = bench.test_manifest(doc, abc, root)
    path = elsewhere / "test.yaml"
    path.write_text(yaml.safe_dump(tman, sort_keys=False))
    loaded = load_manifest(path, require_train_and_test=False)
    assert [f.name for f in loaded.flights] == list(abc.test_flights)
    assert {f.set for f in loaded.flights} == {"swap_abc", "day23_swap_abc"}  # evaluate's per-set keys


def test_goals() -> None:
    assert bench.meets({"ratio_fz": 0.49, "rmse_fz_g": 2.4, "coverage_90": 0.9}) == {
        "ratio": True,
        "grams": True,
        "coverage": True,
    }
    assert bench.meets({"ratio_fz": 0.51, "rmse_fz_g": 2.6, "coverage_90": 0.8}) == {
        "ratio": False,
        "grams": False,
        "coverage": False,
    }
    assert bench.meets(None)["ratio"] is None
