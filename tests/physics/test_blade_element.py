"""Blade-element momentum theory (S1-4..S1-8) -> b_v (S0-5)."""

import dataclasses

import pytest

from proxplan.physics.builtin_vehicles import BUILTIN_VEHICLES, LARGE_QUAD
from proxplan.physics.propeller import derived_b_v, relative_thrust_sensitivity_spm, thrust_coefficient

PAPER_B_V = 3.710e-7  # S0 IV-C, 8-inch propeller, N m^-1 rad^-2 s^3


def test_derived_b_v_of_the_8_inch_propeller_is_near_the_measured_value():
    prop = dataclasses.replace(LARGE_QUAD.propeller, b_v_measured=None)
    b_v = derived_b_v(prop, hover_thrust_N=LARGE_QUAD.hover_thrust_per_rotor_N)
    assert PAPER_B_V / 2 < b_v < PAPER_B_V * 2, b_v


def test_oncoming_flow_lowers_thrust_and_the_momentum_feedback_halves_the_bare_slope():
    prop = LARGE_QUAD.propeller
    assert thrust_coefficient(prop, 0.02) < thrust_coefficient(prop, 0.0) < thrust_coefficient(prop, -0.02)
    # Bare blade-element slope dC_T/dlambda = -a sigma B^2 / 4; with the induced-flow feedback of
    # momentum theory (S1-7) the slope w.r.t. the oncoming flow is less than half of it.
    bare = prop.lift_slope_per_rad * prop.solidity * prop.tip_loss_factor**2 / 4
    slope = (thrust_coefficient(prop, 1e-4) - thrust_coefficient(prop, -1e-4)) / 2e-4
    assert 0.0 < -slope < 0.5 * bare


def test_hover_thrust_coefficient_is_physical():
    for v in BUILTIN_VEHICLES.values():
        ct = thrust_coefficient(v.propeller, 0.0)
        assert 0.002 < ct < 0.03, (v.name, ct)  # typical rotor C_T (omega R form)
        assert 0.0 < relative_thrust_sensitivity_spm(v.propeller, v.hover_thrust_per_rotor_N) < 0.5


def test_every_vehicle_has_a_positive_b_v():
    for v in BUILTIN_VEHICLES.values():
        assert v.b_v > 0.0
    assert LARGE_QUAD.b_v == pytest.approx(PAPER_B_V)
