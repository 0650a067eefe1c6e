"""3-D wrench table: the disturbance model sampled on an (x, y, dz) grid, with a smooth interpolant.

Frames: world z up; both vehicles hover level with aligned axes (as in :mod:`proxplan.physics.disturbance`).
The table holds the wrench on ``target`` in the downwash of a hovering ``source`` at offsets
``p_target - p_source = (x, y, -dz)``; dz > 0 means the target is below. In the axial-flow model of
(S0-3..S0-8) the force is vertical and the yaw torque is zero, so three channels are stored:
F_z (N), tau_x (N m), tau_y (N m).

Numbers come from :func:`proxplan.physics.disturbance.disturbance_wrench` (one physics implementation). The
model is evaluated on one quadrant (x >= 0, y >= 0) and mirrored: the source field is axisymmetric
and the X-frame target is symmetric under x -> -x and y -> -y, under which
F_z(-x, y) = F_z(x, y), tau_x(-x, y) = tau_x(x, y), tau_y(-x, y) = -tau_y(x, y) and
F_z(x, -y) = F_z(x, y), tau_x(x, -y) = -tau_x(x, y), tau_y(x, -y) = tau_y(x, y)
(tests/test_wrench_table.py checks the interpolant against the direct model on random points of all
four quadrants).

Interpolant: a tensor-product cubic B-spline through the samples (not-a-knot), fitted once with
SciPy; the same knots and coefficients are evaluated by ``scipy.interpolate.NdBSpline`` (numpy) and
by ``casadi.Function.bspline`` (CasADi, differentiable), so both give the same numbers.

Outside the table the wrench is zero. That is safe because the extent is chosen, and checked at
build time (``boundary_usage``), so that on the table's lateral boundary the target's authority usage
is below ``USAGE_FLOOR`` (0.01), smaller than every cutoff level offered; above the source (dz <= 0)
the model itself gives zero. Beyond ``dz_max_m`` (default max(6 m, 15 L_source), deeper than any
default workspace is tall) the downwash still exists but is not tabulated: ``beyond_dz_usage`` in
the table records the largest usage on its deepest layer so callers can see what is cut off.
By default the table starts where the model becomes valid, dz_min = 3 L_source (S0 II-A). Closer
to the source (0 < dz < dz_min) the first layer is *held* (same lateral offset, dz = dz_min): never
zero there, but not the model's extrapolated near field either, whose floored jet (1/e radius
L_s / (2 sqrt(c_rad)), 7.5 mm for small-quad) is narrower than any affordable lateral grid (the
spline error there reaches tens of % of the peak force). Planners keep targets out of that zone with
the cutoff map's invalid-zone rule (:mod:`proxplan.costmaps.cutoff`). ``TableResolution(dz_min_m=0)``
tabulates the extrapolated near field anyway (``valid`` flags those layers).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from proxplan.costmaps.effects import map_effects, pair_wrench
from proxplan.physics import DEFAULT_OPTIONS, VALIDITY_FACTOR_L, Effect, ModelOptions, Vehicle, authority_usage

if TYPE_CHECKING:  # pragma: no cover
    import casadi

USAGE_FLOOR = 0.01
"""Authority usage below which a disturbance is treated as negligible (table/grid extents), -."""

SPLINE_DEGREE = 3
CHANNELS = ("force_z_N", "torque_x_Nm", "torque_y_Nm")


@dataclass(frozen=True)
class TableResolution:
    """Grid of the wrench table.

    Lateral nodes follow the jet: at depth dz the lateral offsets are x = xi * S(dz),
    y = eta * S(dz) with xi, eta on ``n_xy`` uniform nodes in [-1, 1] (odd, so 0 is a node) and the
    half-width S(dz) = h_target + ``lateral_widths`` * w(dz), where w(dz) = sqrt(dz^2 + (L_s/2)^2) /
    sqrt(c_rad) follows the 1/e radius of the Gaussian jet (S0-2) (floored near the source like the
    model) and h_target is the target's arm + propeller radius. ``n_dz`` nodes in
    dz = dz_min + (dz_max - dz_min) u^``dz_power``, u uniform in [0, 1] (dense near the source).
    ``dz_min_m`` None = 3 L_source (start of the valid zone); 0 tabulates the invalid zone too.
    ``dz_max_m`` None = max(6 m, 15 L_source).
    """

    n_xy: int = 41
    n_dz: int = 40
    dz_power: float = 1.6
    lateral_widths: float = 3.5
    dz_min_m: float | None = None
    dz_max_m: float | None = None

    def __post_init__(self) -> None:
        if self.n_xy < 9 or self.n_xy % 2 == 0:
            raise ValueError(f"n_xy must be odd and >= 9, got {self.n_xy}")
        if self.n_dz < 8:
            raise ValueError(f"n_dz must be >= 8, got {self.n_dz}")
        if not self.dz_power >= 1.0:
            raise ValueError(f"dz_power must be >= 1, got {self.dz_power}")
        if self.dz_max_m is not None and not self.dz_max_m > 0.0:
            raise ValueError(f"dz_max_m must be > 0, got {self.dz_max_m}")
        if self.dz_min_m is not None and not self.dz_min_m >= 0.0:
            raise ValueError(f"dz_min_m must be >= 0, got {self.dz_min_m}")


DEFAULT_RESOLUTION = TableResolution()


def default_dz_max_m(source: Vehicle) -> float:
    """Deepest vertical separation tabulated by default, max(6 m, 15 L_source), m."""
    return max(6.0, 15.0 * source.size_m)


def target_half_extent_m(vehicle: Vehicle) -> float:
    """Radius of the disc holding a vehicle's frame and propellers (arm + propeller radius), m."""
    return vehicle.body_radius_m


@dataclass(frozen=True)
class LateralScale:
    """Half-width of the table's lateral extent at depth dz: S(dz) = a + b sqrt(dz^2 + c^2), m.

    Smooth in dz (so the CasADi interpolant stays differentiable); a = h_target (m),
    b = widths / sqrt(c_rad) (-), c = L_source / 2 (m).
    """

    a_m: float
    b: float
    c_m: float

    @classmethod
    def for_pair(cls, source: Vehicle, target: Vehicle, widths: float) -> LateralScale:
        return cls(
            a_m=target_half_extent_m(target),
            b=widths / math.sqrt(source.downwash.c_rad),
            c_m=0.5 * source.size_m,
        )

    def half_width_m(self, dz_m: np.ndarray) -> np.ndarray:
        """S(dz) for dz (any shape), m."""
        dz_m = np.asarray(dz_m, dtype=float)
        return self.a_m + self.b * np.sqrt(dz_m * dz_m + self.c_m * self.c_m)


def _spline_fit(values: np.ndarray, axes: tuple[np.ndarray, ...]) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """Tensor-product cubic interpolating B-spline (not-a-knot) through ``values`` (n0, n1, n2, m)
    on the grids ``axes``: knots per axis and coefficients (n0, n1, n2, m).

    Per axis the not-a-knot knots come from ``scipy.interpolate.make_interp_spline``; the
    coefficients solve the collocation system B c = values along that axis (B = design matrix,
    n x n), applied to all other axes at once.
    """
    from scipy.interpolate import BSpline, make_interp_spline

    coeffs = np.asarray(values, dtype=float)
    knots = []
    for axis, grid in enumerate(axes):
        t = np.asarray(make_interp_spline(grid, np.zeros(grid.size), k=SPLINE_DEGREE).t, dtype=float)
        design = BSpline.design_matrix(grid, t, SPLINE_DEGREE).toarray()  # (n, n)
        moved = np.moveaxis(coeffs, axis, 0)
        solved = np.linalg.solve(design, moved.reshape(grid.size, -1)).reshape(moved.shape)
        coeffs = np.moveaxis(solved, 0, axis)
        knots.append(t)
    return tuple(knots), coeffs


@dataclass(frozen=True)
class WrenchTable:
    """Disturbance on ``target`` from hovering ``source``, model evaluated on an (x, y, dz) grid.

    The grid follows the jet (see :class:`TableResolution`): node (i, j, k) sits at the offset
    p_target - p_source = (xi[i] S(dz[k]), eta[j] S(dz[k]), -dz[k]), world frame, m.

    Arrays: ``xi`` (nx,), ``eta`` (ny,) normalised lateral nodes in [-1, 1], -; ``dz_m`` (nz,)
    vertical separation, positive = target below, m; ``offset_x_m`` (nx, nz) and ``offset_y_m``
    (ny, nz) the lateral node offsets per layer, m (properties); ``force_z_N``, ``torque_x_Nm``,
    ``torque_y_Nm`` (nx, ny, nz) in N and N m (world = body frame, level hover); ``valid`` (nz,)
    dz > 3 L_source. ``boundary_usage``: largest authority usage on the lateral boundary (below
    ``USAGE_FLOOR`` by construction, checked); ``beyond_dz_usage``: largest usage on the deepest layer.
    """

    source_name: str
    target_name: str
    xi: np.ndarray
    eta: np.ndarray
    dz_m: np.ndarray
    scale: LateralScale
    force_z_N: np.ndarray
    torque_x_Nm: np.ndarray
    torque_y_Nm: np.ndarray
    valid: np.ndarray
    boundary_usage: float = 0.0
    beyond_dz_usage: float = 0.0
    _spline: dict = field(default_factory=dict, init=False, repr=False, compare=False, hash=False)

    @property
    def offset_x_m(self) -> np.ndarray:
        """Lateral x offsets of the nodes per layer (nx, nz), m."""
        return self.xi[:, None] * self.scale.half_width_m(self.dz_m)[None, :]

    @property
    def offset_y_m(self) -> np.ndarray:
        """Lateral y offsets of the nodes per layer (ny, nz), m."""
        return self.eta[:, None] * self.scale.half_width_m(self.dz_m)[None, :]

    @property
    def peak_abs_force_N(self) -> float:
        """Largest |F_z| in the table, N."""
        return float(np.max(np.abs(self.force_z_N)))

    def _knots_coeffs(self) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
        if "fit" not in self._spline:
            values = np.stack([self.force_z_N, self.torque_x_Nm, self.torque_y_Nm], axis=-1)
            self._spline["fit"] = _spline_fit(values, (self.xi, self.eta, self.dz_m))
        return self._spline["fit"]

    def _bounds(self) -> np.ndarray:
        """(3, 2) lower/upper bounds of (xi, eta, dz) covered by the table."""
        return np.array([[a[0], a[-1]] for a in (self.xi, self.eta, self.dz_m)])

    def contains(self, offsets_m: np.ndarray) -> np.ndarray:
        """True where offsets (N, 3) = p_target - p_source (m) lie inside the table, shape (N,)."""
        return self._inside(self._table_coords(np.atleast_2d(np.asarray(offsets_m, dtype=float))))

    def _table_coords(self, offsets: np.ndarray) -> np.ndarray:
        dz = -offsets[:, 2]
        dz = np.where(dz > 0.0, np.maximum(dz, self.dz_m[0]), dz)  # hold the first layer above it
        half = self.scale.half_width_m(dz)
        return np.column_stack([offsets[:, 0] / half, offsets[:, 1] / half, dz])

    def _inside(self, points: np.ndarray) -> np.ndarray:
        bounds = self._bounds()
        return np.all((points >= bounds[:, 0]) & (points <= bounds[:, 1]), axis=1)

    def wrench_numpy(self, offsets_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interpolated wrench at offsets (N, 3) or (3,) = p_target - p_source, world frame, m.

        Returns force_N (N, 3) (only z non-zero) and torque_Nm (N, 3) (z zero) about the target's
        centre of mass. Zero outside the table: there the usage is below ``USAGE_FLOOR`` (lateral
        boundary), or the target is above the source (no downwash), or deeper than ``dz_max``.
        Between the source and the first layer (0 < dz < dz_m[0]) the first layer is held.
        """
        from scipy.interpolate import NdBSpline

        offsets = np.atleast_2d(np.asarray(offsets_m, dtype=float))
        if offsets.ndim != 2 or offsets.shape[1] != 3:
            raise ValueError(f"offsets_m must have shape (N, 3), got {np.shape(offsets_m)}")
        points = self._table_coords(offsets)
        inside = self._inside(points)
        if "nd" not in self._spline:
            knots, coeffs = self._knots_coeffs()
            self._spline["nd"] = NdBSpline(knots, coeffs, SPLINE_DEGREE, extrapolate=False)
        values = np.zeros((offsets.shape[0], 3))
        if np.any(inside):
            values[inside] = self._spline["nd"](points[inside])
        force = np.zeros((offsets.shape[0], 3))
        torque = np.zeros((offsets.shape[0], 3))
        force[:, 2] = values[:, 0]
        torque[:, :2] = values[:, 1:]
        return force, torque

    def casadi_function(self) -> casadi.Function:
        """Smooth differentiable f(offset_m 3x1) -> [F_z N, tau_x N m, tau_y N m] 3x1.

        The same cubic B-spline as :meth:`wrench_numpy` (offset = p_target - p_source, world
        frame, m); zero outside the table (an ``if_else`` on the bounds, so the gradient there is 0);
        the first layer held for 0 < dz < dz_m[0].
        """
        if "casadi" in self._spline:
            return self._spline["casadi"]
        import casadi as ca

        knots, coeffs = self._knots_coeffs()
        flat = np.transpose(coeffs, (2, 1, 0, 3)).ravel()  # value fastest, then xi, eta, dz
        spline = ca.Function.bspline("wrench_spline", [list(k) for k in knots], list(flat), [SPLINE_DEGREE] * 3, 3, {})
        offset = ca.MX.sym("offset_m", 3)
        dz = ca.if_else(-offset[2] > 0, ca.fmax(-offset[2], float(self.dz_m[0])), -offset[2])
        sc = self.scale
        half = sc.a_m + sc.b * ca.sqrt(dz * dz + sc.c_m * sc.c_m)
        point = ca.vertcat(offset[0] / half, offset[1] / half, dz)
        bounds = self._bounds()
        inside = 1
        for d in range(3):
            inside = ca.logic_and(inside, ca.logic_and(point[d] >= bounds[d, 0], point[d] <= bounds[d, 1]))
        out = ca.if_else(inside, spline(point), ca.DM.zeros(3))
        name = "wrench_" + re.sub(r"[^A-Za-z0-9]+", "_", f"{self.source_name} on {self.target_name}")
        fn = ca.Function(name, [offset], [out], ["offset_m"], ["wrench"])
        self._spline["casadi"] = fn
        return fn


def mirror_quadrant(quadrant: np.ndarray, sign_x: float, sign_y: float) -> np.ndarray:
    """Full (2n-1, 2m-1, ...) array from its quadrant (n, m, ...) at xi >= 0, eta >= 0 (node 0
    first): value(-xi, eta) = sign_x value(xi, eta), value(xi, -eta) = sign_y value(xi, eta)."""
    full_x = np.concatenate([sign_x * quadrant[:0:-1], quadrant], axis=0)
    return np.concatenate([sign_y * full_x[:, :0:-1], full_x], axis=1)


def table_dz_grid_m(source: Vehicle, resolution: TableResolution) -> np.ndarray:
    """dz nodes (nz,) of the table, m: dz_min + (dz_max - dz_min) u^p, u uniform in [0, 1]."""
    dz_max = resolution.dz_max_m or default_dz_max_m(source)
    dz_min = VALIDITY_FACTOR_L * source.size_m if resolution.dz_min_m is None else resolution.dz_min_m
    if not dz_max > dz_min:
        raise ValueError(f"dz_max_m ({dz_max} m) must exceed dz_min_m ({dz_min} m)")
    return dz_min + (dz_max - dz_min) * np.linspace(0.0, 1.0, resolution.n_dz) ** resolution.dz_power


def build_wrench_table(
    source: Vehicle,
    target: Vehicle,
    *,
    options: ModelOptions = DEFAULT_OPTIONS,
    resolution: TableResolution = DEFAULT_RESOLUTION,
    effects: Sequence[Effect] = (),
) -> WrenchTable:
    """Evaluate the disturbance model (plus the between-vehicle ``effects`` that keep the jet
    axisymmetric, :func:`proxplan.costmaps.effects.map_effects`) on the table grid (one quadrant, mirrored)
    and check extents. The yaw torque of an effect (wake swirl) is not a table channel; the cutoff
    map's usage and the verifier include it."""
    scale = LateralScale.for_pair(source, target, resolution.lateral_widths)
    dz = table_dz_grid_m(source, resolution)
    # dz = 0 holds the limit from below the source (the model is zero at and above the rotor plane)
    dz_eval = np.maximum(dz, 1e-6 * source.size_m)
    axis = np.linspace(-1.0, 1.0, resolution.n_xy)
    half = resolution.n_xy // 2
    axis[half] = 0.0
    quad = axis[half:]  # xi >= 0, includes 0
    qx, qy, qz = np.meshgrid(quad, quad, dz_eval, indexing="ij")
    width = scale.half_width_m(qz)
    offsets = np.column_stack([(qx * width).ravel(), (qy * width).ravel(), -qz.ravel()])
    force, torque = pair_wrench(source, target, offsets, options, map_effects(effects))
    shape = qx.shape
    fz_q = force[:, 2].reshape(shape)
    tx_q = torque[:, 0].reshape(shape)
    ty_q = torque[:, 1].reshape(shape)
    usage_q = authority_usage(target, force, torque).reshape(shape)

    boundary = max(float(usage_q[-1, :, :].max()), float(usage_q[:, -1, :].max()))
    return WrenchTable(
        source_name=source.name,
        target_name=target.name,
        xi=axis.copy(),
        eta=axis.copy(),
        dz_m=dz,
        scale=scale,
        force_z_N=mirror_quadrant(fz_q, 1.0, 1.0),
        torque_x_Nm=mirror_quadrant(tx_q, 1.0, -1.0),
        torque_y_Nm=mirror_quadrant(ty_q, -1.0, 1.0),
        valid=dz > VALIDITY_FACTOR_L * source.size_m,
        boundary_usage=boundary,
        beyond_dz_usage=float(usage_q[:, :, -1].max()),
    )
