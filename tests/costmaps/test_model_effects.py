"""A calibrated model's effects between vehicles reach cost maps, planner, plan.json, verify and the
simulator's default world, through one implementation (proxplan.costmaps.pair_wrench over proxplan.physics.total_wrench)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from proxplan.costmaps import build_pair_maps, load_pair_maps, pair_wrench, param_hash, save_pair_maps
from proxplan.costmaps.cutoff import CutoffResolution
from proxplan.costmaps.wrench_table import TableResolution
from proxplan.fileio import UserError
from proxplan.physics import (
    BUILTIN_VEHICLES,
    CalibratedModel,
    Effect,
    EffectInputs,
    SourceSample,
    authority_usage,
    total_wrench,
    write_model_file,
)

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "neural_swarm_stack.yaml"
SMALL, LARGE = BUILTIN_VEHICLES["small-quad"], BUILTIN_VEHICLES["large-quad"]
STRONG = Effect("near_field", {"amplitude": 2.0, "decay_L": 10.0})  # doubles the downwash near the source
BIAS = Effect("thrust_bias", {"force_z_N": 0.05})  # target-only: never applied by planning
COARSE = {
    "cutoff_resolution": CutoffResolution(n_r=31, n_dz=24, n_azimuth=3),
    "table_resolution": TableResolution(n_xy=13, n_dz=12),
}


def test_pair_wrench_is_total_wrench_of_one_source_without_target_only_effects() -> None:
    rng = np.random.default_rng(3)
    offsets = np.column_stack([rng.uniform(-0.3, 0.3, (20, 2)), -rng.uniform(0.2, 1.5, 20)])
    f, t = pair_wrench(SMALL, LARGE, offsets, effects=(STRONG, BIAS))
    inputs = EffectInputs(LARGE, np.full(20, 1e6), np.zeros((20, 3)), (SourceSample(SMALL, offsets),))
    f_ref, t_ref = total_wrench(inputs, (STRONG,))
    np.testing.assert_allclose(f, f_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(t, t_ref, rtol=1e-12, atol=1e-15)
    f0, _ = pair_wrench(SMALL, LARGE, offsets)
    assert np.all(np.abs(f[:, 2]) >= np.abs(f0[:, 2]))  # the strong near field only adds
    assert np.abs(f[:, 2]).sum() > 1.5 * np.abs(f0[:, 2]).sum()


def test_sources_wrench_of_a_stack_is_the_sum_of_pairs_for_effects_that_add() -> None:
    """Without stack shielding (eta = 0) effects that add over sources give the per-pair sum; with the
    default shielding the stack's wrench is smaller than that sum (proxplan.physics.stack)."""
    from proxplan.costmaps import sources_wrench
    from proxplan.physics import ModelOptions

    rng = np.random.default_rng(5)
    upper = np.column_stack([rng.uniform(-0.2, 0.2, (15, 2)), -rng.uniform(0.6, 1.5, 15)])
    middle = np.column_stack([rng.uniform(-0.2, 0.2, (15, 2)), -rng.uniform(0.3, 0.6, 15)])
    effects = (STRONG, Effect("thrust_quadratic", {}), BIAS)
    additive = ModelOptions(stack_shielding=0.0)
    f, t = sources_wrench(SMALL, [(LARGE, upper), (SMALL, middle)], additive, effects=effects)
    f1, t1 = pair_wrench(LARGE, SMALL, upper, additive, effects=effects)
    f2, t2 = pair_wrench(SMALL, SMALL, middle, additive, effects=effects)
    np.testing.assert_allclose(f, f1 + f2, rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(t, t1 + t2, rtol=1e-10, atol=1e-15)
    assert np.all(np.abs(f1[:, 2]) > 0) and np.all(np.abs(f2[:, 2]) > 0)
    no_effect = (Effect("thrust_quadratic", {}),)  # adds over sources, scales with the base as shielded
    fs, _ = sources_wrench(SMALL, [(LARGE, upper), (SMALL, middle)], effects=no_effect)
    fa = (
        pair_wrench(LARGE, SMALL, upper, effects=no_effect)[0] + pair_wrench(SMALL, SMALL, middle, effects=no_effect)[0]
    )
    assert np.all(np.abs(fs[:, 2]) <= np.abs(fa[:, 2])) and np.any(np.abs(fs[:, 2]) < 0.95 * np.abs(fa[:, 2]))


def test_cost_maps_change_with_effects_and_their_hash_tells_them_apart(tmp_path: Path) -> None:
    base = build_pair_maps(LARGE, SMALL, **COARSE)
    strong = build_pair_maps(LARGE, SMALL, effects=(STRONG, BIAS), **COARSE)
    assert strong.cutoff.usage.max() > 1.5 * base.cutoff.usage.max()
    valid = base.cutoff.valid
    level = 0.1
    r_base, r_strong = (
        base.cutoff.r_cut_m(base.cutoff.dz_m[valid], level=level),
        strong.cutoff.r_cut_m(base.cutoff.dz_m[valid], level=level),
    )
    assert np.all(r_strong >= r_base - 1e-9) and r_strong.max() > r_base.max() + 0.02
    assert np.abs(strong.table.force_z_N).max() > 1.5 * np.abs(base.table.force_z_N).max()
    # target-only effects do not change a map or its hash (shipped maps stay valid)
    assert param_hash(LARGE, SMALL, effects=(BIAS,)) == param_hash(LARGE, SMALL) == base.metadata["param_hash"]
    assert strong.metadata["param_hash"] != base.metadata["param_hash"]
    assert [e["name"] for e in strong.metadata["model"]["effects"]] == ["near_field"]
    path = save_pair_maps(strong, tmp_path / "strong.npz")
    with pytest.raises(UserError, match="effects"):
        load_pair_maps(path, expect_source=LARGE, expect_target=SMALL)
    load_pair_maps(path, expect_source=LARGE, expect_target=SMALL, effects=(STRONG,))


def test_scenario_takes_a_model_file_and_plan_json_carries_its_effects(tmp_path: Path) -> None:
    from proxplan.planfile import load_scenario, scenario_from_dict

    model_path = write_model_file(CalibratedModel(effects=(STRONG, BIAS)), tmp_path / "model.yaml")
    text = SCENARIO.read_text() + f"model_file: {model_path}\n"
    (tmp_path / "s.yaml").write_text(text)
    scenario = load_scenario(tmp_path / "s.yaml")
    assert scenario.effects == (STRONG,)
    assert any("thrust_bias" in n for n in scenario.load_notes)
    spec = scenario.to_spec()
    assert "model_file" not in spec and spec["model"]["effects"][0]["name"] == "near_field"
    again = scenario_from_dict(spec, vehicle_types={n: t.vehicle for n, t in scenario.vehicles.items()})
    assert again.effects == (Effect("near_field", STRONG.full_params()),)
    assert load_scenario(SCENARIO).effects == ()


def test_plan_with_a_strong_effect_changes_and_verify_agrees_with_the_planner(tmp_path: Path, capsys) -> None:
    from proxplan.cli import main
    from proxplan.planfile import read_plan
    from proxplan.verify import scenario_of_plan, verify_plan, wrench_along_plan

    model_path = write_model_file(CalibratedModel(effects=(STRONG,)), tmp_path / "model.yaml")
    docs = {}
    for tag, extra in (("base", []), ("model", ["--model", str(model_path)])):
        argv = ["plan", str(SCENARIO), "--out", str(tmp_path / tag), "--method", "sampling", "--no-plot", "--json"]
        assert main(argv + extra) == 0
        docs[tag] = json.loads(capsys.readouterr().out)
        assert docs[tag]["verify"]["passed"]
    usage = {tag: doc["metrics"]["max_authority_usage"] for tag, doc in docs.items()}
    assert usage["model"] > 1.5 * usage["base"] > 0.0
    plan = read_plan(tmp_path / "model")
    assert [e.name for e in plan.effects] == ["near_field"]
    scenario = scenario_of_plan(plan)  # the verifier's view: effects from plan.json alone
    assert scenario.effects == plan.effects and not verify_plan(plan, scenario)
    along = wrench_along_plan(plan, scenario, t_s=plan.t_s)
    # same grid as the planner's metrics; plan.json rounds positions to 1 um, hence rel 1e-4
    assert max(float(w.usage.max()) for w in along.values()) == pytest.approx(usage["model"], rel=1e-4)
    # the verifier sums pair_wrench over sources: same as the physics with every source at once
    target, source = plan.vehicles["cf51"], plan.vehicles["cf101"]
    off = target.position_m - source.position_m
    below = off[:, 2] < -1e-6
    inputs = EffectInputs(
        target.vehicle,
        np.full(below.sum(), 1e6),
        np.zeros((below.sum(), 3)),
        (SourceSample(source.vehicle, off[below]),),
    )
    f_ref, t_ref = total_wrench(inputs, plan.effects)
    np.testing.assert_allclose(
        along["cf51"].usage[below], authority_usage(target.vehicle, f_ref, t_ref), rtol=1e-9, atol=1e-12
    )
    # verify --model re-checks the base plan with the strong model: higher usage than the plan says
    assert main(["verify", str(tmp_path / "base"), "--model", str(model_path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["passed"]
    base_plan = read_plan(tmp_path / "base")
    strong_view = dataclasses.replace(scenario_of_plan(base_plan), effects=plan.effects)
    u_strong = wrench_along_plan(base_plan, strong_view, t_s=base_plan.t_s)
    assert float(u_strong["cf51"].usage.max()) > 1.5 * usage["base"]


def test_simulator_default_world_is_the_plans_model(tmp_path: Path) -> None:
    from proxplan.flightsim import TruthSpec, merge_truth, plan_truth
    from proxplan.planfile import Plan

    spec = {"model": {"field_form": "printed", "effects": [{"name": "near_field", "params": {"amplitude": 2.0}}]}}
    plan = Plan(scenario="x", dt_s=0.1, vehicles={}, scenario_spec=spec)
    world = plan_truth(plan)
    assert world.field_form == "printed" and [e.name for e in world.effects] == ["near_field"]
    extra = TruthSpec(effects=(Effect("near_field", {"amplitude": 0.1}), BIAS), field_form="printed")
    merged = merge_truth(world, extra)
    assert [(e.name, e.full_params().get("amplitude")) for e in merged.effects] == [
        ("near_field", 0.1),
        ("thrust_bias", None),
    ]


@pytest.mark.parametrize("command", ["plan", "costmap", "verify"])
def test_bad_model_file_is_one_line_error_exit_2(tmp_path: Path, capsys, command: str) -> None:
    from proxplan.cli import main

    bad = tmp_path / "bad.yaml"
    bad.write_text("format_version: 2\nvehicles: {}\nmodel: {effects: [{name: vortex_ring}]}\n")
    argv = {
        "plan": ["plan", str(SCENARIO), "--out", str(tmp_path / "o")],
        "costmap": ["costmap", "--source", "small-quad", "--target", "large-quad", "--out", str(tmp_path / "m.npz")],
        "verify": ["verify", str(tmp_path / "nothing.json")],
    }[command]
    if command == "verify":  # a plan to verify, so that the model file is what fails
        assert main(["plan", str(SCENARIO), "--out", str(tmp_path / "p"), "--method", "sampling", "--no-plot"]) == 0
        argv = ["verify", str(tmp_path / "p")]
        capsys.readouterr()
    assert main([*argv, "--model", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(bad) in err and "vortex_ring" in err and "near_field" in err
    assert not (tmp_path / "o").exists() and not (tmp_path / "m.npz").exists()


def test_costmap_command_applies_the_model(tmp_path: Path, capsys) -> None:
    from proxplan.cli import main

    model_path = write_model_file(CalibratedModel(effects=(STRONG, BIAS)), tmp_path / "model.yaml")
    docs = {}
    for tag, extra in (("base", []), ("model", ["--model", str(model_path)])):
        argv = ["costmap", "--source", "large-quad", "--target", "small-quad", "--out", str(tmp_path / f"{tag}.npz")]
        assert main([*argv, "--no-plot", "--json", *extra]) == 0
        captured = capsys.readouterr()
        docs[tag] = json.loads(captured.out)
    assert "thrust_bias" in captured.err  # the target-only effect is named as not applied
    assert docs["base"]["effects"] == [] and [e["name"] for e in docs["model"]["effects"]] == ["near_field"]
    assert docs["model"]["param_hash"] != docs["base"]["param_hash"]
    assert docs["model"]["peak_usage_valid_zone"] > 1.5 * docs["base"]["peak_usage_valid_zone"]
