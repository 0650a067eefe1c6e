"""A bound, for every t >= 0, on the output of a damped linear loop left to itself: x' = A x (every
eigenvalue of A in the open left half-plane), output C x, from x(0) = z,

    |C e^{A t} z| <= sum_m |M_m z| e^{-r_m t},

with the terms m (:class:`ModalBound`) built from A's spectral projectors, one per *cluster* of
eigenvalues (not one per eigenvector). Used for what a loop can still do after the samples it was
stepped over (:mod:`proxplan.physics.hover_loop`, :mod:`proxplan.physics.tracking_loop`).

**Derivation.** A = V diag(lambda) V^-1 (eig's computed V: a nearly defective A comes out with
nearly parallel columns and eigenvalues split by ~ sqrt(eps)), so e^{At} = sum_i e^{lambda_i t} P_i
with P_i = v_i w_i (w_i: row i of V^-1), the spectral projector of lambda_i. A cluster m (eigenvalues
within :data:`CLUSTER_RTOL` of the spectral radius of one another, joined transitively), with lambda_m
its member of largest real part, a_m = -Re lambda_m > 0, delta_i = lambda_i - lambda_m (Re delta_i
<= 0) and P_m = sum_{i in m} P_i:

    C e^{At} P_m z = e^{lambda_m t} (C P_m z + sum_i (e^{delta_i t} - 1) C P_i z),

|e^{delta t} - 1| = |int_0^t delta e^{delta s} ds| <= |delta| t, and t e^{-a t} <= 2/(e a) e^{-a t / 2}, so

    |C e^{At} P_m z| <= |C P_m z| e^{-a_m t} + sum_i (2 |delta_i| / (e a_m)) |C P_i z| e^{-a_m t / 2}:

one term (M = C P_m, r = a_m) per cluster and one (M = 2 |delta_i| C P_i / (e a_m), r = a_m / 2) per
further member; summed over the clusters (triangle inequality) a sound bound for any grouping. For
simple, separated eigenvalues it is the modal bound sum_i |C v_i| |w_i z| e^{Re lambda_i t} the
modules used before (|C P_i z| = |C v_i| |w_i z|, P_i of rank 1).

**Why clusters.** The loops are symmetric in x and y: their eigenvalues come in exactly equal pairs,
whose eigenvectors span a plane in which any basis is an eigenvector basis. The sum over a basis then
depends on the basis eig happens to return (on the CPU's BLAS kernel: the hold bound of a tracking
loop came out 13 % apart between OpenBLAS's Haswell and SkylakeX kernels, stop 49), where P_m, the
projector onto the plane, does not, and |C P_m z| <= sum_i |C P_i z|. Equal eigenvalues computed in
floating point differ by ~ eps x their condition x the radius; a pair made defective by a jet splits
by ~ sqrt(eps) x the radius: :data:`CLUSTER_RTOL` groups both and leaves genuinely distinct modes
apart. Rates 1/s, A in 1/s; C, z in the loop's units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CLUSTER_RTOL = float(np.sqrt(np.finfo(float).eps))
"""Eigenvalues closer than this times the spectral radius are one cluster, -: the split of a double
eigenvalue by rounding is ~ eps (semisimple) to ~ sqrt(eps) (defective) of the radius (module
docstring). Any grouping is sound; this one only decides which split pairs share a projector."""


@dataclass(frozen=True)
class ModalBound:
    """The terms of the bound |C e^{At} z| <= sum_m |maps[m] z| e^{-rate_ps[m] t} (module
    docstring): ``rate_ps`` (M,), 1/s, and ``maps`` (M, p, n), complex (p outputs, n states)."""

    rate_ps: np.ndarray
    maps: np.ndarray

    def weights(self, z: np.ndarray) -> np.ndarray:
        """|maps[m] z| (M, k) for each column of ``z`` (n, k): the terms at t = 0."""
        return np.linalg.norm(np.einsum("mpn,nk->mpk", self.maps, z), axis=1)

    def operator_norms(self, b: np.ndarray) -> np.ndarray:
        """||maps[m] b||_2 (M,), the spectral norm: the largest |maps[m] b u| over |u| <= 1 (b (n, q))."""
        return np.linalg.norm(np.einsum("mpn,nq->mpq", self.maps, b), ord=2, axis=(1, 2))


def modal_bound(a: np.ndarray, c: np.ndarray) -> ModalBound | None:
    """The bound's terms (module docstring) for the loop ``a`` (n, n), 1/s, and output ``c``
    (p, n); None for a loop that is not damped (an eigenvalue with Re >= 0)."""
    lam, vec = np.linalg.eig(a)
    if lam.size and float(lam.real.max()) >= 0.0:
        return None
    inv = np.linalg.inv(vec)
    cv = c @ vec  # (p, n): C v_i
    tol = CLUSTER_RTOL * float(np.abs(lam).max(initial=0.0))
    label = np.arange(lam.size)  # clusters: join eigenvalues within tol, transitively
    close = np.abs(lam[:, None] - lam[None, :]) <= tol
    for _ in range(lam.size):
        joined = np.where(close, label[None, :], lam.size).min(axis=1)
        if np.array_equal(joined, label):
            break
        label = joined
    rates, maps = [], []
    for m in np.unique(label):
        members = np.flatnonzero(label == m)
        lead = members[np.argmax(lam[members].real)]
        rate = -float(lam[lead].real)
        rates.append(rate)
        maps.append(cv[:, members] @ inv[members])  # C P_m
        for i in members[members != lead]:
            rates.append(rate / 2.0)
            maps.append(2.0 * abs(lam[i] - lam[lead]) / (np.e * rate) * np.outer(cv[:, i], inv[i]))
    return ModalBound(np.array(rates), np.array(maps))
