"""Priors of every fitted parameter: the built-in value with a stated spread (issue 35).

The calibration (:mod:`proxplan.identify.calibrate`) is a MAP fit: the data term, in units of the
measurement noise per independent sample, plus one term per parameter, ((value - center) / sigma)^2
(of ln(value) for a :attr:`Prior.log` prior). A parameter the data do not inform stays at its prior
and is reported as uninformed; it can no longer run to a bound and pin another effect out.

Spreads (one sigma) and where they come from:

* ``c_ax`` (axial decay of the jet, S0-1), ``c_rad`` (radial spreading, S0-2): log-normal, sigma of
  ln = ln 2. S0 IV-B fits c_ax = 4.67-4.89 and c_rad = 24.9-60.8 on two vehicles (a factor 2.4 apart);
  the round-jet constants S0 compares with (its ref [13]) lie within a factor 2 of them; a multirotor
  wake (four merged rotor jets, swirl) is known no better than that.
* ``z0_m`` (virtual origin, S0-1): normal, sigma = L (the vehicle size): S0's fits put it within a
  fraction of L of the rotor plane.
* ``b_v`` (thrust loss per oncoming speed, S0-5): log-normal, sigma of ln = ln 2: blade-element theory
  (S1-4..S1-8) lands within a factor 2 of S0's measured value for the 8-inch propeller (docs/model.md).
* ``thrust_scale`` (logged motor thrust over delivered): normal, center 1, sigma 0.1: a static
  PWM-to-thrust map (Foerster 2015's for the Crazyflie) moves by up to 10 % with propellers and
  battery.
* ``stack_shielding`` (eta of :mod:`proxplan.physics.stack`): normal, center 1 (every stream tube a lower
  source intercepts replaced by its own jet, the model's default), sigma 1 (0, S0's per-pair sum, and 2 both
  within one sigma); fitted only where the data hold stacks.
* effects: a strength parameter (:data:`proxplan.physics.effects.EFFECT_STRENGTHS`) is centred on 0
  (the effect off) with sigma = a quarter of its fit range (the range then spans +-2 sigma); a shape
  parameter (a decay length, a convection speed) on its library default, log-normal with sigma of ln
  = ln 3 (a shape is known within a factor 3). ``thrust_bias.force_z_N`` (one absolute force shared by
  every type) is held at 0 (sigma 0): a thrust error is per type, relative to the vehicle's thrust
  (the per-type thrust scales), and one force for a 32 g and a 650 g vehicle pinned the small one's
  scale (issue 35).

:data:`INFORMED_RATIO` and :data:`MOVE_SIGMAS` say how the report reads a fitted parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from proxplan.physics import EFFECT_STRENGTHS, PARAMETERS, Vehicle

INFORMED_RATIO = 1.0 / math.sqrt(2.0)
"""A parameter is informed by the data when its posterior sigma is at most this times its prior sigma:
the data then carry at least as much information (precision) as the prior, -."""
MOVE_SIGMAS = 3.0
"""A fitted parameter this many prior sigmas from its center is reported as a sign of a missing effect
(two-sided probability 0.27 % under the prior); discovery then also searches the prior model's residual, -."""
SHAPE_LOG_SIGMA = math.log(3.0)
"""Prior sigma of ln(shape parameter) of an effect (a factor 3), -."""
JET_LOG_SIGMA = math.log(2.0)
"""Prior sigma of ln(c_ax), ln(c_rad) and ln(b_v) (a factor 2), -."""
THRUST_SCALE_SIGMA = 0.1
"""Prior sigma of a per-type thrust scale (10 % thrust-map error), -."""
HELD_AT_ZERO = {"thrust_bias": ("force_z_N",)}
"""Effect parameters held at their default in identification (prior sigma 0)."""


@dataclass(frozen=True)
class Prior:
    """Gaussian prior of one parameter: of its value, or of ln(value) when ``log``.

    ``center`` is in the parameter's own unit; ``sigma`` too, or of ln(value) (dimensionless) when
    ``log``. ``sigma == 0`` holds the parameter at ``center``."""

    center: float
    sigma: float
    log: bool = False
    basis: str = ""  # where the spread comes from (the module docstring's item)

    def z(self, value: float) -> float:
        """Standardised distance of ``value`` from the center, in prior sigmas (signed), -."""
        if self.sigma <= 0.0:
            return 0.0
        if self.log:
            return (math.log(max(value, 1e-300)) - math.log(self.center)) / self.sigma
        return (value - self.center) / self.sigma

    def relative_std(self, value: float, std: float) -> float:
        """A posterior ``std`` (parameter unit) at ``value`` over this prior's sigma, on the prior's scale
        (ln for a log prior), -."""
        if self.sigma <= 0.0:
            return 0.0
        return (std / max(abs(value), 1e-300) if self.log else std) / self.sigma


STACK_SHIELDING_PRIOR = Prior(1.0, 1.0, basis="the model's default eta 1; 0 and 2 within one sigma")
"""Prior of the stack shielding eta (module docstring)."""


def vehicle_priors(vehicle: Vehicle, *, as_source: bool, as_target: bool) -> dict[str, Prior]:
    """Priors of the declared parameters of ``vehicle`` (module docstring): c_ax, z0_m, c_rad when it is
    a source in the data, b_v when it receives a downwash, and its thrust scale."""
    d = vehicle.downwash
    out: dict[str, Prior] = {}
    if as_source:
        out["c_ax"] = Prior(d.c_ax, JET_LOG_SIGMA, log=True, basis="S0 IV-B c_ax, factor 2")
        out["z0_m"] = Prior(d.z0_m, vehicle.size_m, basis="within one vehicle size L of the rotor plane")
        out["c_rad"] = Prior(d.c_rad, JET_LOG_SIGMA, log=True, basis="S0 IV-B c_rad, factor 2")
    if as_target:
        out["b_v"] = Prior(vehicle.b_v, JET_LOG_SIGMA, log=True, basis="blade-element b_v (S1-4..8), factor 2")
    out["thrust_scale"] = Prior(1.0, THRUST_SCALE_SIGMA, basis="static PWM-to-thrust map, 10 %")
    return out


def effect_prior(effect: str, param: str) -> Prior:
    """Prior of one parameter of a library effect (module docstring)."""
    default, lower, upper = PARAMETERS[effect][param]
    if param in HELD_AT_ZERO.get(effect, ()):
        return Prior(default, 0.0, basis="held: a thrust error is per type (thrust scales)")
    # a strength whose zero switches the effect off (and lies in its range); a decay length is one too
    # (EFFECT_STRENGTHS) but its zero is outside the range: it is a shape
    if param in EFFECT_STRENGTHS.get(effect, ()) and lower <= 0.0 <= upper:
        return Prior(0.0, (upper - lower) / 4.0, basis="strength: 0 (off), a quarter of its range")
    if default > 0.0 and lower > 0.0:
        return Prior(default, SHAPE_LOG_SIGMA, log=True, basis="shape: library default, factor 3")
    return Prior(default, (upper - lower) / 4.0, basis="a quarter of its range")
