"""The multi-scale kernels of a neighbour above, below or beside the target: the spatial families of the
discovery dictionary (:mod:`proxplan.physics.features`), on a declared grid and at any refined scale.

A kernel is a radial profile across (of rho over its width w L) times a decay along (of delta over its decay
length d L), L the neighbour's size (m), gated to the place of the neighbour (:class:`BasisKernel`):

* above (the neighbour over the target): rho = r the horizontal distance, delta = dz > 0 its height over the target;
* below (the neighbour under it): rho = r, delta = -dz > 0 its depth under the target;
* side (any neighbour, the coordinates swapped): rho = |dz|, delta = r, the decay along Gaussian.

Each comes alone (``_1``), times the offset's x or y over L (``_x_1``, ``_y_1``: which side of the target the
neighbour is on, so a force off its centre is a torque), and times the relative horizontal speed
(``_rel_speed_xy_mps``, :data:`BASIS_SPEED`). Names hold the scales they are computed with
(``above_g0p774L_e2p31L_1``), so a kernel refined off the grid (:mod:`proxplan.identify.refine`) is saved and
evaluated by its name like any feature of the dictionary (:func:`parse_basis_name`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

__all__ = [
    "BASIS_DECAYS_L",
    "BASIS_DECAY_FORMS",
    "BASIS_PLACES",
    "BASIS_RADIALS",
    "BASIS_SPEED",
    "BASIS_WIDTHS_L",
    "LEVER_AXES",
    "BasisKernel",
    "basis_columns",
    "basis_kernels",
    "basis_name",
    "parse_basis_name",
    "scale_tag",
]

BASIS_PLACES = ("above", "below", "side")
"""Where the neighbour is: over the target, under it, or any (coordinates swapped, see the module docstring)."""
BASIS_WIDTHS_L = (0.4, 1.0, 2.5)
"""Radial widths of the multi-scale kernels, in the neighbour's size L, -: a geometric series of ratio 2.5 (the
ratio of the two earlier widths, 1 L and 2.5 L) taken one step down to 0.4 L, of the order of one rotor's
wake (a rotor's radius is 0.22-0.31 L on the built-in types) beside the whole vehicle's jet. Stop 54 found the
misses of the kernel family beside and below were kernels narrower than the narrowest width (0.77 L against
1 L), their stable candidates the wider ones that lose on flights held out (docs/identify.md, stop 58)."""
BASIS_DECAYS_L = (1.0, 4.0)
"""Decay lengths of the multi-scale kernels along the distance from the neighbour, in L, -."""
BASIS_DECAY_FORMS = {"above": ("e", "i"), "below": ("e", "i"), "side": ("e",)}
"""Forms of the decay along the depth x = delta / (d L) from the neighbour, per place (since stop 64): "e"
exponential exp(-x), "i" algebraic 1 / (1 + x). An exponential decay cannot carry a heavy tail to a flight
at another depth (it falls e-fold per decay length, a power law does not): a round jet's centre-line velocity
falls as 1 / depth in its far field, the form of the jet kernel's 1 / (1 + dz / L) (S0-1, S0-2), so the
algebraic form is the far field of the same physics at the basis's decay lengths. Beside the target the
coordinate along is the horizontal distance, whose reach across the room stays Gaussian (a heavy tail there
would couple every pair in the room), so "e" alone; the name keeps "e" for that Gaussian, -."""
BASIS_RADIALS = {"above": ("g",), "below": ("g",), "side": ("g", "l", "c")}
"""Radial profiles of the multi-scale kernels, per place of the neighbour: "g" a Gaussian exp(-(rho / w L)^2),
"l" a Laplace (exponential) exp(-rho / w L), heavier-tailed: the two bracket a profile between them where the
flights see few radial positions and a term must carry to others. A neighbour BESIDE the target has its
radial coordinate in the height difference, which each flight holds nearly fixed (its layers), so the tail
there decides what carries to a flight at another gap; its reach across the room is still the Gaussian
decay along the horizontal distance; "c" a Cauchy (Lorentzian) 1 / (1 + (rho / w L)^2) there since stop 64:
the far field of a point disturbance (a tip vortex, a source) falls algebraically with distance, which neither
exponential profile carries to a flight at another gap. Above and below, the radial coordinate is the horizontal
distance, where a Laplace tail would reach across the room (exp(-6) at 15 L for 2.5 L): a jet's profile is
Gaussian (S0-1), -."""
BASIS_SPEED = "rel_speed_xy_mps"
"""Every multi-scale kernel also comes times the relative horizontal speed of its neighbour (m/s), named
``<kernel>_rel_speed_xy_mps`` (since stop 63): a force that grows with how fast two vehicles pass each other
may have any spatial shape the basis spans, not only the jet, core and near kernels' (the velocity family
crossed with the spatial ones). Stop 62 traced a miss (docs/identify.md, stop 62, draw 22019) to a
relative-speed force acting from neighbours above AND below, exp(-|dz| / 3 L), that only one-sided
kernels times the speed could carry, each on half of the data; the side family's Laplace profile in the
height difference spans such a two-sided shape. Declared as the whole cross product (every place, profile,
width and decay), not the one shape traced."""
AXES = ("", "x", "y", "speed")
"""What a kernel is multiplied by: nothing, the offset's x or y over L, the relative horizontal speed."""
LEVER_AXES = {"x": "xt", "y": "yt"}
"""A side axis's LEVER form (issue 35, round 37K): the kernel times the offset's x or y over the TARGET's size
L_t (``_xt_1``, ``_yt_1``), not the neighbour's. On a torque channel a weight-scaled term is c W L_t x feature
(:func:`proxplan.physics.feature_terms.term_scale`), so the side axis gives c W L_t k y / L (the lever arm
rescaled by L_t / L: a coefficient that depends on the pair's sizes) and its lever form c W k y: the force
c W k off the target's centre at its lever arm y (m), one coefficient for any pair of sizes. Which of the two
describes a neighbour's torque is not known a priori (:mod:`proxplan.identify.type_split`'s docstring): the
lever form is offered as an alternative form of a stable side-axis term, not searched as a grid feature, so it
is not in :data:`AXES` (the declared grid)."""
_ACROSS = {"g": "exp(-(rho / {w} L)^2)", "l": "exp(-rho / {w} L)", "c": "1 / (1 + (rho / {w} L)^2)"}
_ALONG = {"e": "exp(-delta / {d} L)", "i": "1 / (1 + delta / {d} L)"}
_WHAT = {
    "above": "a neighbour above (r radial, depth below it along the axis)",
    "below": "a neighbour below (r radial, its depth under the target)",
    "side": "a neighbour beside (height difference radial, horizontal distance along)",
}


def scale_tag(value: float) -> str:
    """A scale as it appears in a feature name: three significant digits, "." written "p" (2.31 -> "2p31"), -."""
    return f"{float(f'{value:.3g}'):g}".replace(".", "p")


@dataclass(frozen=True)
class BasisKernel:
    """One multi-scale kernel: ``where`` one of :data:`BASIS_PLACES`, ``radial`` a profile of
    :data:`BASIS_RADIALS`, ``width_L`` its radial width and ``decay_L`` its decay length (in the neighbour's
    size L, -), ``form`` a decay form of :data:`BASIS_DECAY_FORMS`."""

    where: str
    radial: str
    width_L: float
    form: str
    decay_L: float

    def name(self, axis: str = "") -> str:
        """The feature's name; ``axis`` one of :data:`AXES`."""
        stem = f"{self.where}_{self.radial}{scale_tag(self.width_L)}L_{self.form}{scale_tag(self.decay_L)}L"
        if axis == "speed":
            return f"{stem}_{BASIS_SPEED}"
        return f"{stem}_{axis + '_' if axis else ''}1"

    def doc(self, axis: str = "") -> str:
        """One line saying what the feature ``self.name(axis)`` is."""
        shape = (f"{_ACROSS[self.radial].format(w=f'{self.width_L:g}')} "
                 f"{_ALONG[self.form].format(d=f'{self.decay_L:g}')}")  # fmt: skip
        if axis in ("x", "y"):
            return f"multi-scale kernel of {_WHAT[self.where]} ({shape}) times offset_{axis} / L, summed"
        if axis in LEVER_AXES.values():
            return (
                f"multi-scale kernel of {_WHAT[self.where]} ({shape}) times offset_{axis[0]} / L_target (the "
                "target's size), summed"
            )
        if axis == "speed":
            return f"multi-scale kernel of {_WHAT[self.where]} ({shape}) times the relative horizontal speed, summed"
        return f"multi-scale kernel of {_WHAT[self.where]}: {shape}, summed"

    def value(self, rho_1: np.ndarray, along_1: np.ndarray) -> np.ndarray:
        """The kernel (-) of the radial coordinate over its width ``rho_1`` and the coordinate along over its
        decay length ``along_1`` (both -, before the place's gate); beside the target the decay along is Gaussian."""
        x = np.maximum(along_1, 0.0)
        along_exp = x**2 if self.where == "side" else (x if self.form == "e" else None)
        if self.radial == "c":
            across = 1.0 / (1.0 + rho_1**2)
            return across * (np.exp(-along_exp) if along_exp is not None else 1.0 / (1.0 + x))
        across_exp = rho_1**2 if self.radial == "g" else rho_1
        if along_exp is None:
            return np.exp(-across_exp) / (1.0 + x)
        return np.exp(-across_exp - along_exp)


def basis_kernels(where: str) -> list[BasisKernel]:
    """Every kernel of the declared grid at ``where`` (profiles x widths x decay forms x decay lengths)."""
    return [
        BasisKernel(where, rad, w, form, d)
        for rad in BASIS_RADIALS[where]
        for w in BASIS_WIDTHS_L
        for form in BASIS_DECAY_FORMS[where]
        for d in BASIS_DECAYS_L
    ]


def basis_name(where: str, width: float, decay: float, axis: str = "", radial: str = "g", form: str = "e") -> str:
    """The name of the kernel (``where``, ``radial``, ``width`` L, ``form``, ``decay`` L) times ``axis``."""
    return BasisKernel(where, radial, width, form, decay).name(axis)


_SCALE = r"(\d+(?:p\d+)?)"
_NAME = re.compile(rf"^(above|below|side)_([glc]){_SCALE}L_([ei]){_SCALE}L_(?:(xt|yt|x|y)_1|1|({BASIS_SPEED}))$")


def parse_basis_name(name: str) -> tuple[BasisKernel, str] | None:
    """(kernel, axis) of a multi-scale kernel's feature name, at any positive scale (on the grid or refined
    off it); None for any other name, or a profile or form the place does not declare."""
    m = _NAME.match(name)
    if m is None:
        return None
    where, radial, w, form, d, xy, speed = m.groups()
    if radial not in BASIS_RADIALS[where] or form not in BASIS_DECAY_FORMS[where]:
        return None
    width, decay = float(w.replace("p", ".")), float(d.replace("p", "."))
    if width <= 0.0 or decay <= 0.0:
        return None
    return BasisKernel(where, radial, width, form, decay), ("speed" if speed else (xy or ""))


def basis_columns(
    kernel: BasisKernel,
    axes: tuple[str, ...],
    off_m: np.ndarray,
    size_m: float,
    rel_speed_xy_mps: np.ndarray,
    target_size_m: float | None = None,
) -> dict[str, np.ndarray]:
    """The features ``kernel.name(axis)`` for each of ``axes`` of ONE neighbour at ``off_m`` (N, 3)
    (p_target - p_neighbour, m) of size ``size_m`` (m) moving at ``rel_speed_xy_mps`` (N,) relative to the
    target: name -> (N,) array (a feature is the sum of these over the neighbours). A lever axis
    (:data:`LEVER_AXES`) needs the target's size ``target_size_m`` (m)."""
    dz, r = -off_m[:, 2], np.hypot(off_m[:, 0], off_m[:, 1])
    if kernel.where == "above":
        rho, delta, gate = r, dz, dz > 0.0
    elif kernel.where == "below":
        rho, delta, gate = r, -dz, dz < 0.0
    else:
        rho, delta, gate = np.abs(dz), r, np.ones(len(r), dtype=bool)
    k = np.where(gate, kernel.value(rho / (kernel.width_L * size_m), delta / (kernel.decay_L * size_m)), 0.0)
    by_axis = {"": k, "x": k * off_m[:, 0] / size_m, "y": k * off_m[:, 1] / size_m, "speed": k * rel_speed_xy_mps}
    if any(a in LEVER_AXES.values() for a in axes):
        if target_size_m is None:
            raise ValueError(f"{kernel.name(axes[0])}: a lever axis needs the target's size")
        by_axis |= {"xt": k * off_m[:, 0] / target_size_m, "yt": k * off_m[:, 1] / target_size_m}
    return {kernel.name(a): by_axis[a] for a in axes}
