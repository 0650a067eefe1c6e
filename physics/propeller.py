"""Propeller specification and the blade-element momentum theory of seed 001 (derives b_v).

For an axial oncoming flow ``v_on`` (from above, along the rotor axis) the advance ratio is zero and
the oncoming flow adds to the inflow like a climb: lambda = lambda_c + lambda_i with
lambda_c = v_on / (omega R) (S1-2). Blade-element theory at constant pitch (S1-5, mu = 0)

    C_T = (a sigma / 2) (B^3 theta / 3 - B^2 lambda / 2)

and momentum theory (S1-7, mu = 0)

    C_T = 2 lambda_i lambda = 2 (lambda - lambda_c) lambda

are equated (S1-8); for mu = 0 this is a quadratic in lambda with the closed-form root used below.

The seed-000 model writes the thrust change as Delta f = -b_v v_on omega^2 (S0-5, S0-6), so at hover
b_v = k1 * s with s = -(1/T) dT/dv_on the relative thrust loss per unit oncoming speed, s/m.
The relative sensitivity s comes from the theory; k1 is the propeller's own (measured) constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

AIR_DENSITY_KGPM3 = 1.225
"""ISA sea-level air density, kg/m^3."""


@dataclass(frozen=True)
class PropellerSpec:
    """One propeller type (all rotors of a vehicle share it).

    ``thrust_coefficient`` is the static C_T of T = C_T rho n^2 D^4 (n in rev/s), the form of
    propeller data sheets; the S0 constant k1 (T = k1 omega^2) follows from it.
    ``chord_m``, ``pitch_m``, ``n_blades``, ``lift_slope_per_rad`` and ``tip_loss_factor`` feed the
    blade-element theory of seed 001 (S1-3..S1-8) used to derive ``b_v`` when none is measured.
    """

    diameter_m: float
    chord_m: float  # blade chord at 75 % radius, m
    pitch_m: float  # geometric pitch (advance per revolution), m
    n_blades: int  # blades per propeller, -
    thrust_coefficient: float  # static C_T (rev/s form), -
    lift_slope_per_rad: float = 5.7  # 2-D lift-curve slope a, 1/rad (S1 Table 1: 5.9 +- 0.2)
    tip_loss_factor: float = 0.9  # B, - (S1 Table 1)
    b_v_measured: float | None = None  # thrust decay coefficient, N m^-1 rad^-2 s^3 (S0-5)

    @property
    def radius_m(self) -> float:
        return 0.5 * self.diameter_m

    @property
    def disk_area_m2(self) -> float:
        return math.pi * self.radius_m**2

    @property
    def k1_Ns2prad2(self) -> float:
        """Thrust constant k1 of f = k1 omega^2 (S0-5), N s^2 rad^-2."""
        return self.thrust_coefficient * AIR_DENSITY_KGPM3 * self.diameter_m**4 / (4.0 * math.pi**2)

    @property
    def solidity(self) -> float:
        """Rotor solidity sigma = N c / (pi R) (S1-3), -."""
        return self.n_blades * self.chord_m / (math.pi * self.radius_m)

    @property
    def pitch_angle_rad(self) -> float:
        """Blade pitch at 75 % radius, theta = atan(pitch / (2 pi 0.75 R)), rad."""
        return math.atan(self.pitch_m / (2.0 * math.pi * 0.75 * self.radius_m))


def thrust_coefficient(prop: PropellerSpec, climb_inflow_ratio: float) -> float:
    """Rotor C_T (omega R form, (S1-6)) at axial inflow ratio lambda_c = v_on / (omega R), -.

    Solves (S1-5) = (S1-7) with mu = 0 for the total inflow ratio lambda, then evaluates (S1-5).
    """
    a, sigma, b, theta = (
        prop.lift_slope_per_rad,
        prop.solidity,
        prop.tip_loss_factor,
        prop.pitch_angle_rad,
    )
    k_static = a * sigma * b**3 * theta / 6.0  # (a sigma / 2) B^3 theta / 3
    k_inflow = a * sigma * b**2 / 4.0  # (a sigma / 2) B^2 / 2
    # 2 lambda^2 + (k_inflow - 2 lambda_c) lambda - k_static = 0, positive root
    p = k_inflow - 2.0 * climb_inflow_ratio
    lam = (-p + math.sqrt(p * p + 8.0 * k_static)) / 4.0
    return k_static - k_inflow * lam


def relative_thrust_sensitivity_spm(prop: PropellerSpec, hover_thrust_N: float) -> float:
    """s = -(1/T) dT/dv_on at constant omega, at the rotor speed that holds ``hover_thrust_N``, s/m."""
    ct_hover = thrust_coefficient(prop, 0.0)
    if ct_hover <= 0.0:
        raise ValueError("blade-element C_T is not positive: check pitch, chord and lift slope")
    tip_speed_mps = math.sqrt(hover_thrust_N / (ct_hover * AIR_DENSITY_KGPM3 * prop.disk_area_m2))
    step = 1e-4
    dct_dlambda = (thrust_coefficient(prop, step) - thrust_coefficient(prop, -step)) / (2.0 * step)
    return -dct_dlambda / (ct_hover * tip_speed_mps)


def derived_b_v(prop: PropellerSpec, *, hover_thrust_N: float) -> float:
    """Thrust decay coefficient b_v of (S0-5) from blade-element theory, N m^-1 rad^-2 s^3."""
    return prop.k1_Ns2prad2 * relative_thrust_sensitivity_spm(prop, hover_thrust_N)
