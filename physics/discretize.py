"""Exact discretisation of linear time-invariant pieces x' = a x + b u over one step h: the
zero-order hold (u constant over the step) and the first-order hold (u linear between the
samples), from one matrix exponential of the augmented system (Van Loan), for stacks of systems;
and the discrete recursion x[k+1] = Phi x[k] + f[k] run over a whole drive (:func:`recurrence`).
Used by :mod:`proxplan.physics.closed_loop` and the closed loops of :mod:`proxplan.physics.hover_loop` and
:mod:`proxplan.physics.tracking_loop`. Units: those of x, u and h (s)."""

from __future__ import annotations

import numpy as np


def expm_stack(m: np.ndarray) -> np.ndarray:
    """exp of a stack of square matrices (K, n, n): scaling and squaring with a degree-12 Taylor
    polynomial (the scaled 1-norm <= 1/2, so the truncated terms are below 1e-13 of the sum), all
    samples at once."""
    norm = float(np.abs(m).sum(axis=-2).max(initial=0.0))
    squarings = max(0, int(np.ceil(np.log2(max(norm, 1e-300) / 0.5))))
    x = m / 2.0**squarings
    eye = np.broadcast_to(np.eye(m.shape[-1]), m.shape)
    out = eye.copy()
    for k in range(12, 0, -1):  # Horner: I + x/12 (I + x/11 (...))
        out = eye + (x @ out) / k
    for _ in range(squarings):
        out = out @ out
    return out


def zoh_maps(a: np.ndarray, b: np.ndarray, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold maps (Phi (K, n, n), Gamma (K, n, m)) of x' = a x + b u over ``step_s``:
    x[k+1] = Phi x[k] + Gamma u[k]."""
    k, n, m = b.shape
    aug = np.zeros((k, n + m, n + m))
    aug[:, :n, :n] = a
    aug[:, :n, n:] = b
    e = expm_stack(aug * step_s)
    return e[:, :n, :n], e[:, :n, n:]


def foh_maps(a: np.ndarray, b: np.ndarray, step_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order-hold maps (Phi, Gamma_0, Gamma_1) of x' = a x + b u over ``step_s`` (a (n, n),
    b (n, m)): x[k+1] = Phi x[k] + Gamma_0 u[k] + Gamma_1 (u[k+1] - u[k]), exact for u linear
    between the samples (exp of [[a h, b h, 0], [0, 0, I], [0, 0, 0]] = [[Phi, Gamma_0, Gamma_1], ...])."""
    n, m = b.shape
    aug = np.zeros((1, n + 2 * m, n + 2 * m))
    aug[0, :n, :n] = a * step_s
    aug[0, :n, n : n + m] = b * step_s
    aug[0, n : n + m, n + m :] = np.eye(m)
    e = expm_stack(aug)[0]
    return e[:n, :n], e[:n, n : n + m], e[:n, n + m :]


def recurrence(phi: np.ndarray, forced: np.ndarray) -> np.ndarray:
    """x[k+1] = Phi x[k] + forced[k] from x[0] = 0: the states x[1..K] (n, ..., K) for ``phi``
    (n, n) and ``forced`` (n, ..., K) (component first, time last; axes between: drives run side
    by side). Stepped, in blocks of L ~ sqrt(K) steps: every block's response from rest stepped
    side by side, then the states between blocks stepped with Phi^L, then each block's free
    response Phi^j x_start added: ~2 sqrt(K) Python-level steps. Only products with Phi and its
    powers: no eigenvector basis (ill-conditioned, or, for the loops' equal x-y eigenvalue pairs,
    not unique) and no Schur form (the back-substitution amplifies its large off-diagonal terms):
    the same numbers, to rounding (~1e-14 relative), as stepping one sample at a time, whatever the
    CPU's BLAS kernel."""
    n, k = phi.shape[0], forced.shape[-1]
    size = max(1, int(np.ceil(np.sqrt(k))))  # L
    blocks = -(-k // size)
    lead = forced.shape[1:-1]
    pad = np.zeros((n, int(np.prod(lead)), blocks * size))
    pad[..., :k] = forced.reshape(n, -1, k)
    steps = np.ascontiguousarray(pad.reshape(n, -1, blocks, size).transpose(3, 0, 1, 2))  # (L, n, drives, blocks)
    steps = steps.reshape(size, n, -1)
    x = np.zeros(steps.shape[1:])
    for j in range(size):  # every block from rest, side by side
        x = phi @ x + steps[j]
        steps[j] = x
    powers = phi[None]  # Phi^(j+1), j < L, by doubling
    while powers.shape[0] < size:
        powers = np.concatenate([powers, powers[-1] @ powers])
    powers = powers[:size]
    end = steps[-1].reshape(n, -1, blocks)  # each block's last state from rest
    start = np.zeros((blocks, n, end.shape[1]))  # the state entering each block
    for b in range(1, blocks):
        start[b] = powers[-1] @ start[b - 1] + end[..., b - 1]
    steps += powers @ start.transpose(1, 2, 0).reshape(n, -1)  # + Phi^(j+1) x_start
    out = steps.reshape(size, n, -1, blocks).transpose(1, 2, 3, 0).reshape(n, -1, blocks * size)
    return out[..., :k].reshape(n, *lead, k)
