"""A thrust scale's tangent (identify/design.py): the measurement reads a disturbance F as
F / s + (1 - 1/s) m (g + a_z), so a step in u = 1 - 1/s along the analytic column is EXACT, at any
reference scale, where the old step in s was only a linearisation (a constant offset on the type's
samples, 1.3 mN on a 67 g vehicle for a step of 0.046)."""

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

from proxplan.identify.calibrate import ParamSpec
from proxplan.identify.data import Model, thrust_scaled
from proxplan.identify.design import apply_tangent_step, tangent_columns, tangent_ridge, tangent_u
from proxplan.identify.noise import stacked
from proxplan.identify.priors import Prior
from proxplan.physics import BUILTIN_VEHICLES

TYPE = "crazyflie-parrot"
NAME = f"{TYPE}.thrust_scale"


@dataclass
class _Unit:
    """The fields of identify.data.Unit that the thrust-scale column reads."""

    type: str
    thrust_kin_z_N: np.ndarray

    def __len__(self) -> int:
        return len(self.thrust_kin_z_N)


def _measured(force_N, torque_Nm, s, unit, model) -> np.ndarray:
    f, t = thrust_scaled(force_N.copy(), torque_Nm.copy(), s, unit, model)
    return stacked(f, t)


@pytest.mark.parametrize("s_ref", [1.0, 1.055, 0.93])
def test_a_step_in_u_reads_exactly_what_the_column_predicts(s_ref: float):
    rng = np.random.default_rng(7)
    n = 200
    weight_N = BUILTIN_VEHICLES[TYPE].weight_N
    kin = weight_N * (1.0 + 0.1 * rng.normal(size=n))  # m (g + a_z), N
    force = 0.02 * rng.normal(size=(n, 3))  # disturbance, N
    torque = 2e-4 * rng.normal(size=(n, 3))  # N m
    unit = _Unit(TYPE, kin)
    model = Model(vehicles={TYPE: BUILTIN_VEHICLES[TYPE]}, thrust_scale={TYPE: s_ref})
    predicted = _measured(force, torque, s_ref, unit, model)
    sel = SimpleNamespace(units=[unit], model=model, weight=np.ones(n), predicted=predicted, row_scale=np.ones((n, 4)))
    spec = ParamSpec(NAME, s_ref, 0.7, 1.3, Prior(1.0, 0.1))
    col = tangent_columns(sel, [spec])[NAME]
    for du in (0.046, -0.08):
        moved = apply_tangent_step(model, [spec], {NAME: du})
        s_new = moved.thrust_scale[TYPE]
        assert tangent_u(moved, spec) == pytest.approx(tangent_u(model, spec) + du, abs=1e-12)
        exact = _measured(force, torque, s_new, unit, model)
        np.testing.assert_allclose(exact, predicted + du * col, rtol=0, atol=1e-12)
        # the same move linearised in s (the old coordinate) is off by a constant of order du^2 m g: the
        # check above is sharp enough to see it
        linear_in_s = predicted + (s_new - s_ref) * col / s_ref**2
        assert np.max(np.abs(linear_in_s - exact)) > 1e-4


def test_the_prior_of_a_thrust_scale_maps_to_u_by_its_slope():
    s_ref = 1.04
    model = Model(vehicles={TYPE: BUILTIN_VEHICLES[TYPE]}, thrust_scale={TYPE: s_ref})
    sel = SimpleNamespace(model=model)
    spec = ParamSpec(NAME, s_ref, 0.7, 1.3, Prior(1.0, 0.1))
    ridge = tangent_ridge(sel, [spec], [NAME])  # type: ignore[arg-type]
    assert ridge.center[0] == pytest.approx(0.0 - (1.0 - 1.0 / s_ref))  # u_prior - u_ref
    assert ridge.precision[0] == pytest.approx(1.0 / 0.1**2)  # sigma / s0^2 at s0 = 1


@pytest.mark.parametrize("s_ref", [1.0, 1.045, 0.95])
def test_the_smoothing_correction_is_read_through_the_thrust_scale(s_ref: float):
    """The measurement smooths what it reads, and reads it through the thrust scale: the correction for its
    smoothing (Unit.smoothing_force_N / smoothing_torque_Nm) scales with 1/s like the wrench it corrects, so a
    step in u along the analytic column reads exactly what ``predict`` gives at the new scale, on a unit under
    a jet (added to the reading after the scale, it left (1/s - 1) of the correction behind: 4 % of it at
    s = 1.045, in every flight)."""
    from proxplan.identify.data import Unit, predict

    rng = np.random.default_rng(3)
    n = 150
    veh = BUILTIN_VEHICLES[TYPE]
    offsets = np.column_stack([0.05 * rng.normal(size=n), 0.05 * rng.normal(size=n), -0.4 + 0.02 * rng.normal(size=n)])
    kin = veh.weight_N * (1.0 + 0.05 * rng.normal(size=n))
    zeros = np.zeros((n, 3))
    unit = Unit("f", "train", "v", TYPE, np.arange(n) * 0.01, zeros, np.full(n, 1.0), kin, (TYPE,), (offsets,),
                zeros, zeros, thrust_kin_z_N=kin, smoothing_force_N=0.01 * rng.normal(size=(n, 3)),
                smoothing_torque_Nm=1e-4 * rng.normal(size=(n, 3)))  # fmt: skip
    model = Model(vehicles={TYPE: veh}, thrust_scale={TYPE: s_ref})
    predicted = stacked(*predict(unit, model))
    sel = SimpleNamespace(units=[unit], model=model, weight=np.ones(n), predicted=predicted, row_scale=np.ones((n, 4)))
    spec = ParamSpec(NAME, s_ref, 0.7, 1.3, Prior(1.0, 0.1))
    col = tangent_columns(sel, [spec])[NAME]
    for du in (0.03, -0.05):
        moved = apply_tangent_step(model, [spec], {NAME: du})
        np.testing.assert_allclose(stacked(*predict(unit, moved)), predicted + du * col, rtol=0, atol=1e-12)
