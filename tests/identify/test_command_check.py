"""How the logged motor command runs between samples is chosen per vehicle type from free flight
(proxplan.identify.command_check): a log that writes the command once per sample is held (p = 0, the
exact inverse); a log that samples a command written five times faster is read interpolated, and the
measured free-flight force comes out steadier so."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from proxplan.identify import synthetic_logs, write_synthetic_manifest
from proxplan.identify.command_check import check_loaded_holds
from proxplan.identify.data import IdentifyOptions
from proxplan.identify.loading import load_units
from proxplan.identify.manifest import load_manifest
from proxplan.identify.measure import MeasureOptions

TYPE = "crazyflie-2.1"
OPTIONS = MeasureOptions()


def _holds(tmp: Path, *, written_per_sample: int, n_flights: int = 4, motor_noise_N: float = 0.0) -> dict:
    """Single-vehicle flights weaving at 1-2 Hz well above the ground (free flight), their commanded thrust
    written ``written_per_sample`` times per 10 ms log sample by the controller (the motors' exact
    zero-order-hold inverse at that rate) and logged every 10 ms."""
    from proxplan.physics import BUILTIN_VEHICLES

    cf = BUILTIN_VEHICLES[TYPE]
    dt = 0.01 / written_per_sample
    t = dt * np.arange(int(round(12.0 / dt)))
    flights = []
    for k in range(n_flights):
        w = 6.0 + 0.7 * k
        pos = np.column_stack([0.05 * np.sin(w * t), 0.04 * np.sin(0.8 * w * t + k), 0.9 + 0.01 * np.sin(1.7 * w * t)])
        logs = synthetic_logs({"a": cf}, {"a": pos}, t, accel_noise_mps2=0.01, seed=k, motor_noise_N=motor_noise_N,
                              motor_time_constant_s=cf.motor_time_constant_s)  # fmt: skip
        rows = np.arange(0, len(t), written_per_sample)
        keep = np.zeros(len(t), dtype=bool)
        keep[rows] = True
        flights.append(
            (f"f_{k:02d}", "train" if k < n_flights - 1 else "test", {n: g.take(keep) for n, g in logs.items()})
        )
    path = write_synthetic_manifest(
        tmp / f"w{written_per_sample}_{n_flights}_{motor_noise_N:g}", flights, TYPE, motor_thrust="commanded"
    )
    manifest = load_manifest(path)
    data = load_units(manifest, options=IdentifyOptions(measure=OPTIONS), thrust_coefficient_samples=False)
    return check_loaded_holds(data, motor_thrust="commanded", options=OPTIONS)


def test_a_command_written_once_per_sample_is_held(tmp_path: Path) -> None:
    hold = _holds(tmp_path, written_per_sample=1)[TYPE]
    assert hold.interpolation == 0.0, hold
    assert hold.n_flights == 3  # train flights only: the test flight is never looked at
    # p = 0 is the exact inverse: interpolating makes F_z less steady beyond chance (t of 48 measured)
    assert hold.t_stat["1"]["F_z"] > 10.0, hold.t_stat


def test_a_command_written_faster_than_logged_is_interpolated(tmp_path: Path) -> None:
    hold = _holds(tmp_path, written_per_sample=5)[TYPE]
    assert hold.interpolation > 0.0, hold
    best = f"{hold.interpolation:g}"
    # the synthetic vehicle's motors turn together (no roll or pitch torque), so F_z carries the evidence:
    # 1.72 mN held, 1.18 mN at the p taken (0.5; measured)
    assert hold.spread[best]["F_z"] < 0.8 * hold.spread["0"]["F_z"], hold.spread


def test_command_noise_is_no_evidence_of_interpolation(tmp_path: Path) -> None:
    """Interpolating averages neighbouring samples and so steadies any command noise whatever the timing; a
    command written once per sample with noise on it (4 mN a motor) stays held: only timing is evidence
    (command_check.phase_of_hold keeps the noise's power)."""
    hold = _holds(tmp_path, written_per_sample=1, motor_noise_N=0.004)[TYPE]
    assert hold.interpolation == 0.0, hold


@pytest.mark.parametrize("n_flights", [3])
def test_too_few_flights_keep_the_hold_and_say_so(tmp_path: Path, n_flights: int) -> None:
    hold = _holds(tmp_path, written_per_sample=5, n_flights=n_flights)[TYPE]
    assert hold.interpolation == 0.0 and hold.n_flights == 2
    assert "fewer than 3" in hold.reason


def test_the_chosen_hold_is_saved_with_the_model_and_read_back() -> None:
    """evaluate measures other days as identify did: the hold per type travels in ``model.measurement``."""
    from proxplan.identify.evaluate import measurement_dict, measurement_from_model
    from proxplan.physics import CalibratedModel

    opts = MeasureOptions(command_interpolation_by_type=((TYPE, 1.0),))
    saved = CalibratedModel(vehicles={}, measurement=measurement_dict(opts, {}))
    assert saved.measurement["command_interpolation"] == {TYPE: 1.0}
    back, _, notes = measurement_from_model(saved, "m.yaml")
    assert back.command_interpolation_by_type == ((TYPE, 1.0),) and notes == []
    older = CalibratedModel(
        vehicles={}, measurement={k: v for k, v in saved.measurement.items() if k != "command_interpolation"}
    )
    assert measurement_from_model(older, "m.yaml")[0].command_interpolation_by_type == ()


def test_the_hold_is_chosen_on_samples_flown_alone(tmp_path: Path) -> None:
    """A neighbour BESIDE (no source overhead: still "free flight") is near for the first half of each flight and
    far for the second: the check's samples (``alone``) leave out the first half, the motor-lag check's keep it."""
    from proxplan.identify.data import NEIGHBOUR_REACH_L, neighbours_near
    from proxplan.identify.motor_check import lag_samples
    from proxplan.physics import BUILTIN_VEHICLES

    cf = BUILTIN_VEHICLES[TYPE]
    t = 0.01 * np.arange(800)
    near_m = 0.5 * NEIGHBOUR_REACH_L * cf.size_m  # beside at half the reach, then 4 reaches away
    far_m = 4.0 * NEIGHBOUR_REACH_L * cf.size_m
    gap = np.where(t < 4.0, near_m, far_m)
    flights = []
    for k in range(3):
        a = np.column_stack([0.03 * np.sin(6.0 * t + k), np.zeros_like(t), np.full_like(t, 1.0)])
        b = a + np.column_stack([gap, np.zeros_like(t), np.full_like(t, -0.02)])  # level, a little lower: not overhead
        logs = synthetic_logs({"a": cf, "b": cf}, {"a": a, "b": b}, t, accel_noise_mps2=0.01, seed=k)
        flights.append((f"f_{k}", "train" if k < 2 else "test", logs))
    data = load_units(load_manifest(write_synthetic_manifest(tmp_path / "beside", flights, TYPE)),
                      options=IdentifyOptions(measure=OPTIONS), thrust_coefficient_samples=False)  # fmt: skip
    for u in data.units:
        near = neighbours_near(u, data.types)
        assert near[u.t_s < 3.9].all() and not near[u.t_s > 4.1].any()
    units = [u for u in data.units if u.split == "train"]  # lag_samples' own order: train flights, every vehicle
    free, alone = lag_samples(data), lag_samples(data, alone=True)
    assert [s.flight for s in free] == [u.flight for u in units] == [s.flight for s in alone]
    beside_only = 0
    for u, f, a in zip(units, free, alone):
        near = neighbours_near(u, data.types)
        assert np.array_equal(a.free, f.free & ~near)
        beside_only += int(np.sum(f.free & near))
    assert beside_only > 300  # vehicle a's first half: free flight, yet its neighbour is beside it


def test_one_hold_for_the_log_source_every_type_pooled(tmp_path: Path) -> None:
    """Two types logged by one logger (a command written once per sample, held): one verdict for both (the same
    flights, the same t statistics), each type with its own free-flight spreads."""
    from proxplan.physics import BUILTIN_VEHICLES

    types = {"a": "crazyflie-2.1", "b": "crazyflie-parrot"}
    assert {BUILTIN_VEHICLES[ty].motor_time_constant_s for ty in types.values()} == {0.072}  # the logs' own lag
    t = 0.01 * np.arange(1200)
    flights = []
    for k in range(4):
        w = 6.0 + 0.7 * k
        a = np.column_stack([0.05 * np.sin(w * t), 0.04 * np.sin(0.8 * w * t + k), 0.9 + 0.01 * np.sin(1.7 * w * t)])
        b = a[:, [1, 0, 2]] + np.array([5.0, 0.0, 0.3])  # far off: each flies alone
        logs = synthetic_logs({n: BUILTIN_VEHICLES[ty] for n, ty in types.items()}, {"a": a, "b": b}, t,
                              accel_noise_mps2=0.01, seed=k, motor_time_constant_s=0.072)  # fmt: skip
        flights.append((f"f_{k:02d}", "train" if k < 3 else "test", logs))
    path = write_synthetic_manifest(tmp_path / "two", flights, types, motor_thrust="commanded")
    data = load_units(load_manifest(path), options=IdentifyOptions(measure=OPTIONS), thrust_coefficient_samples=False)
    holds = check_loaded_holds(data, motor_thrust="commanded", options=OPTIONS)
    assert set(holds) == set(types.values())
    cf, parrot = holds["crazyflie-2.1"], holds["crazyflie-parrot"]
    assert cf.interpolation == parrot.interpolation == 0.0, (cf, parrot)
    assert cf.n_flights == parrot.n_flights == 3 and cf.t_stat == parrot.t_stat and cf.t_stat
    assert "2 vehicle type(s) of the log source pooled" in cf.reason
    assert cf.spread and parrot.spread and cf.spread["0"] != parrot.spread["0"]
