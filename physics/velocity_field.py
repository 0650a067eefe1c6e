"""Downwash velocity field below a hovering source multirotor (S0-1, S0-2).

Frame: world z up. A point below the source at vertical distance ``dz_m`` (positive downwards from
the source's centre of mass) and horizontal distance ``r_m`` from its axis sees an axial (downward)
flow speed V(dz, r) >= 0, in m/s.

Two named forms of the centreline decay (S0-1):

``"inverse-z"`` (default)
    V_max = sqrt(T / (2 rho A_p)) * c_ax L / (dz - z0): a momentum-conserving round jet, speed ~ 1/z.
``"printed"``
    V_max = sqrt(T / (2 rho A_p) * c_ax L / (dz - z0)): (S0-1) exactly as printed, speed ~ 1/sqrt(z).

DESIGN.md section 2 gives the evidence for the default; ``tests/test_disturbance.py`` keeps it.
The radial profile is Gaussian in r / (dz - z0) (S0-2). T is the source's per-rotor hover thrust and
A_p its propeller disk area.

Outside the zone of established flow (dz <= 3 L) the formulas are still evaluated (the caller gets
a validity flag); to keep them finite, dz - z0 is floored at half the source size, and points at or
above the source's rotor plane (dz <= 0) see no flow.
"""

from __future__ import annotations

import math
from typing import Literal, get_args

import numpy as np

from proxplan.physics.propeller import AIR_DENSITY_KGPM3
from proxplan.physics.vehicles import Vehicle

FieldForm = Literal["inverse-z", "printed"]
"""The forms of (S0-1): the 1/z decay (default, DESIGN.md section 2) and the printed 1/sqrt(z)."""
FIELD_FORMS: tuple[str, ...] = get_args(FieldForm)
DEFAULT_FIELD_FORM = "inverse-z"


def induced_velocity_mps(source: Vehicle, air_density_kgpm3: float = AIR_DENSITY_KGPM3) -> float:
    """Hover induced velocity V_i = sqrt(T / (2 rho A_p)) of one source rotor (S0-1), m/s."""
    return math.sqrt(source.hover_thrust_per_rotor_N / (2.0 * air_density_kgpm3 * source.propeller.disk_area_m2))


def axial_distance_m(source: Vehicle, dz_m: np.ndarray) -> np.ndarray:
    """dz - z0, floored at L/2 so the field stays finite in the near field, m."""
    return np.maximum(dz_m - source.downwash.z0_m, 0.5 * source.size_m)


def centreline_speed_mps(
    source: Vehicle,
    dz_m: np.ndarray,
    *,
    form: str = DEFAULT_FIELD_FORM,
    air_density_kgpm3: float = AIR_DENSITY_KGPM3,
) -> np.ndarray:
    """V_max(dz) of (S0-1) in the named ``form``, any shape, m/s; zero where dz <= 0."""
    dz_m = np.asarray(dz_m, dtype=float)
    v_i = induced_velocity_mps(source, air_density_kgpm3)
    decay = source.downwash.c_ax * source.size_m / axial_distance_m(source, dz_m)
    if form == "inverse-z":
        v_max = v_i * decay
    elif form == "printed":
        v_max = v_i * np.sqrt(decay)
    else:
        raise ValueError(f"unknown field form {form!r}; expected one of {', '.join(FIELD_FORMS)}")
    return np.where(dz_m > 0.0, v_max, 0.0)


def radial_profile(source: Vehicle, r_over_axial_sq: np.ndarray) -> np.ndarray:
    """Gaussian radial factor exp(-c_rad (r / (dz - z0))^2) of (S0-2), given (r / (dz - z0))^2, -."""
    exponent = np.multiply(-source.downwash.c_rad, r_over_axial_sq)
    if isinstance(exponent, np.ndarray) and exponent.ndim > 0:
        return np.exp(exponent, out=exponent)  # in place: batches are large
    return np.exp(exponent)


def downwash_speed_mps(
    source: Vehicle,
    dz_m: np.ndarray,
    r_sq_m2: np.ndarray,
    *,
    form: str = DEFAULT_FIELD_FORM,
    air_density_kgpm3: float = AIR_DENSITY_KGPM3,
) -> np.ndarray:
    """Axial downwash speed V(dz, r) of (S0-2), m/s (broadcast shape of the inputs).

    Takes the squared horizontal distance ``r_sq_m2`` (m^2) so batches avoid a square root.
    """
    dz_m = np.asarray(dz_m, dtype=float)
    axial_m = axial_distance_m(source, dz_m)
    v_max = centreline_speed_mps(source, dz_m, form=form, air_density_kgpm3=air_density_kgpm3)
    return v_max * radial_profile(source, np.asarray(r_sq_m2) / (axial_m * axial_m))
