"""Identification pipeline on synthetic logs with a known hidden effect (must-show of issue 8).

Default run: closed-loop RotorPy flights from the simulator (proxplan.flightsim.simulate.simulate_plan with
``truth_effects``, logs and manifest by proxplan.flightsim.logs.write_flight_logs), one test per effect of
the library plus one without any. Marked slow: the same checks on measurement-level logs from
:func:`proxplan.identify.synthetic_logs.synthetic_logs` (the effect library evaluated along scripted trajectories,
written in the canonical layout), which were the stand-in before the simulator landed.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from proxplan.flightsim.identify_flights import HIDDEN_EFFECTS
from proxplan.identify import (
    IdentifyOptions,
    run_identify,
    synthetic_logs,
    write_canonical_csv,
    write_synthetic_manifest,
)
from proxplan.identify.data import errors as model_errors
from proxplan.physics import BUILTIN_VEHICLES

VEHICLE_TYPE = "small-quad"
HIDDEN = HIDDEN_EFFECTS  # proxplan.flightsim.identify_flights: the named effects at the strengths hidden here
FAST = IdentifyOptions(max_fit_samples=3000, max_eval_samples=2500)


def _trajectories(t: np.ndarray, phase: float) -> dict[str, np.ndarray]:
    """Source 'a' hovers near (0, 0, 1.6); 'b' sweeps below it (dz 0.3-0.9 m, |x| < 0.45 m), then
    dives near the ground (rotor plane 0.05-0.30 m up) while moving, so every effect has support."""
    T = t[-1]
    a = np.column_stack([0.1 * np.cos(2 * np.pi * t / 8 + phase), 0.1 * np.sin(2 * np.pi * t / 8 + phase), 1.6 + 0 * t])
    x = 0.45 * np.sin(2 * np.pi * t / 5.0 + phase)
    y = 0.15 * np.sin(2 * np.pi * t / 7.0 + 2 * phase)
    dz = 0.6 + 0.3 * np.sin(2 * np.pi * t / 6.0 + 3 * phase)
    z_high = 1.6 - dz
    z_low = 0.175 + 0.125 * np.sin(2 * np.pi * t / 3.0 + phase)
    blend = 0.5 * (1 + np.tanh((t - 0.6 * T) / 0.8))
    b = np.column_stack([x, y, (1 - blend) * z_high + blend * z_low])
    return {"a": a, "b": b}


def make_manifest(tmp: Path, effects: tuple, *, n_train: int = 2, duration_s: float = 15.0) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    veh = BUILTIN_VEHICLES[VEHICLE_TYPE]
    t = np.arange(0.0, duration_s, 0.01)
    flights = [
        (f"f{k}", "test" if k == n_train else "train", synthetic_logs(
            {"a": veh, "b": veh}, _trajectories(t, 0.9 * k), t, effects=effects, accel_noise_mps2=0.02, seed=k
        ))
        for k in range(n_train + 1)
    ]  # fmt: skip
    return write_synthetic_manifest(tmp, flights, VEHICLE_TYPE)


@pytest.mark.slow
@pytest.mark.parametrize("hidden", list(HIDDEN))
def test_pipeline_finds_hidden_effect(tmp_path: Path, hidden: str) -> None:
    result = run_identify(make_manifest(tmp_path, (HIDDEN[hidden],)), options=FAST, thrust_summary=False)
    assert hidden in result.selected, (result.selected, [(t.name, t.reason) for t in result.trials])
    if hidden == "wake_swirl":
        assert result.after.rmse_tz_Nm <= 0.5 * result.before.rmse_tz_Nm
    else:
        assert result.after.rmse_fz_N <= 0.5 * result.before.rmse_fz_N


@pytest.mark.slow
def test_no_hidden_effect_selects_nothing_beyond_thrust_bias(tmp_path: Path) -> None:
    result = run_identify(make_manifest(tmp_path, ()), options=FAST, thrust_summary=False)
    assert set(result.selected) <= {"thrust_bias"}, result.selected
    # the model as given is the truth here: after must not be worse than before
    assert result.after.rmse_fz_N <= 1.05 * result.before.rmse_fz_N


@pytest.fixture(scope="module")
def one_train_flight_cli(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, str, str, Path, Path]:
    """``proxplan identify --json --save-model`` run once on one train flight with a hidden thrust bias:
    (exit code, stdout, stderr, --out folder, saved model). The JSON/report/model test and the fallback
    test read the same run (what each of them ran, the fallback test without --save-model)."""
    from contextlib import redirect_stderr, redirect_stdout
    from io import StringIO

    from proxplan.cli import main

    tmp = tmp_path_factory.mktemp("one_train_flight")
    manifest = make_manifest(tmp, (HIDDEN["thrust_bias"],), n_train=1, duration_s=8.0)
    out, model = tmp / "out", tmp / "model.yaml"
    stdout, stderr = StringIO(), StringIO()
    with redirect_stdout(stdout), redirect_stderr(stderr):
        code = main(["identify", str(manifest), "--out", str(out), "--json", "--save-model", str(model)])
    return code, stdout.getvalue(), stderr.getvalue(), out, model


def test_cli_json_report_and_saved_model(one_train_flight_cli) -> None:
    from proxplan.physics import load_model_section, load_vehicle_file

    code, stdout, _, out, model = one_train_flight_cli
    assert code == 0
    doc = json.loads(stdout)
    for key in ("before", "after", "effects", "selected"):
        assert key in doc
    assert {"rmse_fz_N", "rmse_torque_Nm"} <= set(doc["before"]) and {"rmse_fz_N", "rmse_torque_Nm"} <= set(
        doc["after"]
    )
    assert all({"name", "params", "rmse_fz_N"} <= set(e) for e in doc["effects"])
    assert (out / "report.md").exists() and (out / "effects.png").stat().st_size > 1000
    vehicles = load_vehicle_file(model)
    assert VEHICLE_TYPE in vehicles
    effects = load_model_section(model)["effects"]
    assert [e["name"] for e in effects] == doc["selected"]


def test_cli_bad_manifest_is_one_line_error(tmp_path: Path, capsys) -> None:
    from proxplan.cli import main

    bad = tmp_path / "m.yaml"
    bad.write_text("format: neural-swarm\nroot: .\nflights: []\n")
    assert main(["identify", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "m.yaml" in err


# ----------------------------------------------------------------- closed-loop simulator logs (the must-show)


SIMULATOR_OPEN = {  # issue 35, left open (measured on this test's flights; see the note)
    "near_field": pytest.mark.xfail(
        reason="issue 35 open: thrust_quadratic is kept in its place on these seeds (68.9 % of the held-out error; "
        "near_field itself chosen in 20 % of half-samples). With effects read through the measurement's smoothing "
        "(identify.reading) near_field is kept alone in 6 of 7 replicate simulations (seeds k + 1000 r, r = 0..6; "
        "this test's are r = 0), thrust_quadratic in 7 of 7; before, 5 of 7 and 0 of 7 (docs/identify.md, stop 55)",
        strict=False,
    ),
}


def simulator_manifest(tmp: Path, effects: list, *, ground: bool = False) -> Path:
    """Seven closed-loop RotorPy flights with the hidden ``effects`` (:func:`proxplan.flightsim.simulated_swap_manifest`:
    two small quads swapping places stacked 0.3-1.0 m apart, six train flights and a test flight, or take-off/hover
    sweeps near the ground), replicate 0."""
    from proxplan.flightsim import simulated_swap_manifest

    return simulated_swap_manifest(tmp, effects, type_name=VEHICLE_TYPE, ground=ground)


SIMULATOR_INFLOW = ("climb_inflow", "own_velocity")
"""Library effects the simulator's own rotor model holds: RotorPy's induced inflow, f_z,i = k_eta omega^2
- k_z omega v_z (flightsim.dynamics), i.e. a thrust change with the vehicle's own climb speed."""


def _simulator_inflow_cw(root: Path) -> float:
    """c_w (s/m) of the simulator's OWN rotor model on the train flights under ``root``: the world-frame vertical
    force RotorPy's rotor inflow and drag add at each logged state (:func:`proxplan.flightsim.dynamics.state_derivative`
    with and without ``k_z`` and ``k_d``: -omega_i k_z and -omega_i k_d times each rotor's local air velocity, the
    body velocity plus w x r_i), regressed on v_z, per unit weight. In gentle flight it is the hover figure
    k_z / (k_eta omega_hover); a vehicle that tumbles (a hidden yaw torque of 0.05 m x F_z saturates the small
    quad's motors: yaw, roll and pitch rates of several rad/s) adds its rotors' own vertical speeds, and the
    force the v_z term must carry is then up to 1.4x the hover figure (0.0251 against 0.0184 s/m on replicate 0's train flights)."""
    import gzip

    import yaml

    from proxplan.flightsim.dynamics import VehicleConstants, state_derivative
    from proxplan.flightsim.vehicle_params import quad_params

    veh = BUILTIN_VEHICLES[VEHICLE_TYPE]
    const = VehicleConstants.from_params(quad_params(veh))
    still = replace(const, k_z=0.0, k_d=0.0)
    manifest = yaml.safe_load((root / "manifest.yaml").read_text())
    num = den = 0.0
    for flight in manifest["flights"]:
        if flight["split"] != "train":
            continue
        for entry in flight["vehicles"].values():
            with gzip.open(root / entry["log"], "rt") as fh:
                header = fh.readline().lstrip("# ").strip().split(",")
                table = np.loadtxt(fh, delimiter=",", ndmin=2)
            col = {name: k for k, name in enumerate(header)}

            def get(*names: str, table: np.ndarray = table, col: dict = col) -> np.ndarray:
                return table[:, [col[n] for n in names]]

            v = get("vx[m/s]", "vy[m/s]", "vz[m/s]")
            states = np.hstack([np.zeros_like(v), v, get("qx", "qy", "qz", "qw"), get("wx[rad/s]", "wy[rad/s]", "wz[rad/s]"),
                                np.sqrt(np.clip(get("u1[N]", "u2[N]", "u3[N]", "u4[N]"), 0.0, None) / const.k_eta)])  # fmt: skip
            for s in states:
                s = [float(x) for x in s]
                aero_z = (state_derivative(const, s, s[13:17], [0.0] * 3, [0.0] * 3)[5]
                          - state_derivative(still, s, s[13:17], [0.0] * 3, [0.0] * 3)[5]) * const.mass_kg  # fmt: skip
                num += aero_z * s[5]
                den += s[5] * s[5]
    return -num / den / veh.weight_N


def _simulator_inflow_ok(result, root: Path, hidden: str = "") -> None:
    """A kept inflow effect must be the simulator's own rotor inflow: its relative thrust change per m/s of climb
    (climb_inflow: gain b_v / k1; own_velocity: c_w) within 35 % of :func:`_simulator_inflow_cw` on these
    flights (plus the hidden own_velocity's c_w when that is the injected effect)."""
    truth = _simulator_inflow_cw(root)
    if hidden == "own_velocity":
        truth += HIDDEN["own_velocity"].params["c_w_spm"]
    fitted = result.final_model.vehicles[VEHICLE_TYPE]
    for eff in result.final_model.effects:
        if eff.name == "climb_inflow":
            coef = eff.params["gain_1"] * fitted.b_v / fitted.propeller.k1_Ns2prad2
        elif eff.name == "own_velocity":
            coef = eff.params["c_w_spm"]
        else:
            continue
        assert truth / 1.35 < coef < truth * 1.35, (eff, coef, truth)


def _simulator_run(tmp: Path, hidden: str):
    """identify (FAST) on :func:`simulator_manifest`'s flights with ``hidden`` injected, and the flights' folder."""
    manifest = simulator_manifest(tmp, [HIDDEN[hidden]], ground=hidden == "ground_effect")
    return run_identify(manifest, options=FAST, thrust_summary=False), manifest.parent


@pytest.fixture(scope="module")
def thrust_quadratic_run(tmp_path_factory: pytest.TempPathFactory):
    """The simulator's flights with a hidden thrust_quadratic identified once (simulation and identify are
    seeded). Until stop 49 test_indistinguishable_effects_are_named read this run too: the flights could not
    tell near_field from thrust_quadratic (head-to-head +0.19 +- 0.31 in the old bounded log-ratio). With the
    gain per unit of change (identify.crossval) near_field's predictions beat thrust_quadratic's on every one of
    the six flights (ratios 0 to 1.4, R = 0.87 +- 0.18): the premise no longer holds, and the rival naming is
    tested on two near-copies in tests/identify/test_gain_ratio.py."""
    return _simulator_run(tmp_path_factory.mktemp("thrust_quadratic"), "thrust_quadratic")


SIMULATOR_SLOW = ("near_field",)
"""Hidden effects whose simulator run is marked slow (round 32S): near_field's is a non-strict xfail (issue 35 open,
above), which no outcome of fails, so the default run spent ~1 min on it to gate nothing. near_field found in
logs stays covered by default tests: test_every_trial_says_why_with_its_held_out_gain_and_inclusion (kept, with
its held-out gain and inclusion) and tests/identify/test_delays.py::test_a_late_library_effect_is_found_with_its_delay
(kept with its delay and strength); identify on simulator logs by this test's other effects."""


@pytest.mark.parametrize(
    "hidden",
    [
        pytest.param(h, marks=[SIMULATOR_OPEN[h], *([pytest.mark.slow] if h in SIMULATOR_SLOW else [])])
        if h in SIMULATOR_OPEN
        else h
        for h in HIDDEN
    ],
)
def test_simulator_logs_hidden_effect(request: pytest.FixtureRequest, tmp_path: Path, hidden: str) -> None:
    """The hidden effect is found, and no library effect the data do not hold is kept beside it (issue
    29): besides it only thrust_bias and the simulator's own induced inflow, with its own coefficient."""
    if hidden == "thrust_quadratic":
        result, root = request.getfixturevalue("thrust_quadratic_run")
    else:
        result, root = _simulator_run(tmp_path, hidden)
    assert hidden in result.selected, (result.selected, [(t.name, t.reason) for t in result.trials])
    library = {n for n in result.selected if not n.startswith("discovered:")}
    assert library <= {hidden, "thrust_bias", *SIMULATOR_INFLOW}, result.selected
    _simulator_inflow_ok(result, root, hidden)
    if hidden == "wake_swirl":
        assert result.after.rmse_tz_Nm <= 0.5 * result.before.rmse_tz_Nm
    else:
        assert result.after.rmse_fz_N <= 0.5 * result.before.rmse_fz_N


def test_simulator_logs_no_hidden_effect(tmp_path: Path) -> None:
    """No library effect but a thrust bias and the simulator's own induced inflow (with the simulator's
    coefficient) is kept on simulator logs with no effect injected, and what discovery keeps there never
    makes the test error worse than the calibrated model's. (Issue 29's version also expected lagged
    copies of the base torque to be kept, as "the closed loop's delayed torque response". Issue 35 found
    that premise wrong: the measured roll/pitch torque follows the applied one with no lag (correlation
    0.985-0.999 at zero shift), and held out by flight those terms' gains scatter, 0.10 +- 0.12.)"""
    result = run_identify(simulator_manifest(tmp_path, []), options=FAST, thrust_summary=False)
    library = {n for n in result.selected if not n.startswith("discovered:")}
    assert library <= {"thrust_bias", *SIMULATOR_INFLOW}, result.selected
    _simulator_inflow_ok(result, tmp_path)  # issue 29: climb_inflow is kept here, and it is RotorPy's own k_z
    assert result.after.rmse_fz_N <= 1.01 * result.before.rmse_fz_N
    # against the calibrated model read through the thrust scales the final one stands with (result.calibrated
    # has them at 1; with nothing kept the final model IS the calibration's fit with its fitted scales, and a
    # scale of 1.0001 moved the torque error by 0.02 %): what discovery keeps never makes it worse
    test = [u for u in result.units if u.split == "test"]
    calibrated = model_errors(
        test, replace(result.calibrated_model, thrust_scale=dict(result.final_model.thrust_scale))
    )
    assert result.after.rmse_torque_Nm <= calibrated.rmse_torque_Nm
    assert result.after.rmse_tz_Nm <= calibrated.rmse_tz_Nm


# ----------------------------------------------------------------- residual analysis


def test_correlate_finds_the_feature_behind_a_residual() -> None:
    from proxplan.identify.residuals import correlate, sample_features

    rng = np.random.default_rng(0)
    n = 3000
    vel = rng.normal(0, 0.5, (n, 3))
    offsets = [np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), -rng.uniform(0.2, 1.5, n)])]
    feats = sample_features(rng.uniform(0.1, 2.0, n), vel, offsets)
    r = np.hypot(offsets[0][:, 0], offsets[0][:, 1])
    np.testing.assert_allclose(feats["r_m"], r)
    residual = np.exp(-((r / 0.1) ** 2)) + rng.normal(0, 0.05, n)  # a peak at small r: not monotonic in anything else
    ranked = correlate(residual, feats)
    assert ranked[0].feature == "r_m" and ranked[0].eta > 0.5
    assert all(c.strength < 0.2 for c in ranked[1:] if c.feature not in ("r_m",))


def test_quadratic_climb_drag_is_discovered(tmp_path: Path) -> None:
    """A force that follows v_z |v_z| (no effect of the library has that shape) was reported as unexplained,
    with v_z, before issue 35; the declared families now hold v_z |v_z| (own motion), so discovery finds it
    as a term on F_z and the error falls more than fivefold (one train flight: the selection's block
    fallback)."""
    from proxplan.identify import read_log

    manifest = make_manifest(tmp_path, (), n_train=1, duration_s=10.0)
    for path in tmp_path.glob("f*_b.csv.gz"):
        log = read_log(path)
        vz = log.velocity_mps[:, 2]
        acc = log.accel_mps2.copy()
        extra_force_N = 0.3 * vz * np.abs(vz)  # N, with v_z in m/s
        acc[:, 2] += extra_force_N / BUILTIN_VEHICLES[VEHICLE_TYPE].mass_kg
        write_canonical_csv(type(log)(**{**log.__dict__, "accel_mps2": acc}), path)
    result = run_identify(manifest, options=FAST, thrust_summary=False)
    kept = [(e["feature"], e["channel"]) for e in result.discovered if e["selected"]]
    assert ("v_z_abs_m2ps2", "force_z_N") in kept, kept
    assert result.after.rmse_fz_N < result.before.rmse_fz_N / 5.0


def test_every_trial_says_why_with_its_held_out_gain_and_inclusion(tmp_path: Path) -> None:
    """Issue 35: each library candidate is judged by flights held out and by half-samples of the flights;
    its trial carries both figures and the reason; the selection's note says how flights were held out."""
    result = run_identify(make_manifest(tmp_path, (HIDDEN["near_field"],), n_train=3, duration_s=10.0),
                          options=FAST, thrust_summary=False)  # fmt: skip
    assert "near_field" in result.selected, [(t.name, t.reason) for t in result.trials]
    kept = next(t for t in result.trials if t.name == "near_field")
    assert kept.selected and kept.inclusion > 0.5 and kept.gain_last is not None and kept.gain_last.passed
    assert kept.reason.startswith("kept: held-out gain")
    assert all(t.reason for t in result.trials)
    assert result.validation.startswith("selection: each of 3 train flights held out in turn")
    doc = result.to_json()
    assert doc["selection"]["start"] in ("calibrated", "prior") and doc["selection_fallback"] is None


def test_test_flights_never_choose(tmp_path: Path) -> None:
    """Selection without leakage: replacing the test flight's logs changes the reported errors but not what
    is chosen or fitted."""
    from dataclasses import replace

    options = replace(FAST, effects=("near_field", "thrust_bias"), discover=False)
    path = make_manifest(tmp_path / "a", (HIDDEN["near_field"],), n_train=3, duration_s=8.0)
    first = run_identify(path, options=options, thrust_summary=False)
    other = make_manifest(tmp_path / "b", (HIDDEN["wake_advection"],), n_train=3, duration_s=8.0)
    for k in ("f0", "f1", "f2"):
        for v in ("a", "b"):
            (tmp_path / "b" / f"{k}_{v}.csv.gz").write_bytes((tmp_path / "a" / f"{k}_{v}.csv.gz").read_bytes())
    second = run_identify(other, options=options, thrust_summary=False)
    assert second.selected == first.selected
    assert [t.params for t in second.trials] == [t.params for t in first.trials]
    assert second.after.rmse_fz_N != first.after.rmse_fz_N  # the test flight did change


def test_one_train_flight_falls_back_and_says_so(one_train_flight_cli) -> None:
    """Issue 35: a manifest with too few flights to hold one out: selection falls back to blocks in time
    and says so in one line on stderr, in the JSON and in the report; nothing crashes."""
    code, stdout, stderr, out, _ = one_train_flight_cli
    assert code == 0
    doc = json.loads(stdout)
    assert doc["selection_fallback"] and "fell back" in doc["selection_fallback"]
    lines = [ln for ln in stderr.splitlines() if "fell back" in ln]
    assert len(lines) == 1 and "too few flights" in lines[0]
    assert "Selection fell back" in (out / "report.md").read_text()


def test_mixed_types_thrust_error_is_per_type_and_nothing_else_is_kept(tmp_path: Path) -> None:
    """Issue 35: a 145 g and a 650 g vehicle, each with its own thrust-map error (the large one's +3 %), no
    effect: thrust_bias takes one scale per type (within 0.5 % of the truth each), and no velocity or other
    effect is kept beside it (one absolute force for both types pinned the small one's scale before)."""
    from dataclasses import replace as dc_replace

    small, large = BUILTIN_VEHICLES["small-quad"], BUILTIN_VEHICLES["large-quad"]
    errors = {"small-quad": -0.02, "large-quad": 0.03}
    t = np.arange(0.0, 12.0, 0.01)
    flights = []
    for k in range(4):
        paths = _trajectories(t, 0.9 * k)
        paths["a"] = paths["a"] + np.array([0.0, 0.0, 0.4])  # the large one above, 0.7-1.3 m over the small one
        logs = synthetic_logs({"a": large, "b": small}, paths, t, accel_noise_mps2=0.02, motor_noise_N=0.002, seed=k)
        for name, vtype in (("a", "large-quad"), ("b", "small-quad")):
            logs[name] = dc_replace(logs[name], motor_thrust_N=logs[name].motor_thrust_N * (1.0 + errors[vtype]))
        flights.append((f"f{k}", "test" if k == 3 else "train", logs))
    manifest = write_synthetic_manifest(tmp_path, flights, {"a": "large-quad", "b": "small-quad"})
    result = run_identify(manifest, options=FAST, thrust_summary=False)
    assert result.selected == ["thrust_bias"], [(tr.name, tr.reason) for tr in result.trials]
    for vtype, err in errors.items():
        assert result.final_model.thrust_scale[vtype] == pytest.approx(1.0 / (1.0 + err), abs=0.005)


def test_parameters_the_data_do_not_inform_stay_at_their_prior(tmp_path: Path) -> None:
    """Issue 35 (MAP calibration): two vehicles that never fly over each other: the jet's parameters are not
    informed, stay at their priors and are reported so (posterior sigma near the prior's)."""
    veh = BUILTIN_VEHICLES[VEHICLE_TYPE]
    t = np.arange(0.0, 8.0, 0.01)
    apart = {"a": np.column_stack([0.3 * np.sin(t), 0 * t, 1.5 + 0 * t]),
             "b": np.column_stack([3.0 + 0.3 * np.sin(t), 0 * t, 0.9 + 0.1 * np.sin(2 * t)])}  # fmt: skip
    flights = [(f"f{k}", "test" if k == 2 else "train",
                synthetic_logs({"a": veh, "b": veh}, apart, t, accel_noise_mps2=0.02, seed=k)) for k in range(3)]  # fmt: skip
    result = run_identify(write_synthetic_manifest(tmp_path, flights, VEHICLE_TYPE), options=FAST, thrust_summary=False)
    report = result.calibration.prior_report()
    c_ax = report.get(f"{VEHICLE_TYPE}.c_ax")
    if c_ax is not None:  # a source in the data at all (it is 3 m away: the model gives nothing)
        assert not c_ax["informed"] and abs(c_ax["move_sigmas"]) < 0.1, c_ax
    assert result.final_model.vehicles[VEHICLE_TYPE].downwash.c_ax == pytest.approx(veh.downwash.c_ax, rel=0.05)
