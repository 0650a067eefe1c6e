"""The hover loop's response along a plan (:func:`proxplan.physics.hover_loop.jet_response`) as one
time-varying recursion x[k+1] = Phi_k x[k] + w_k from rest, and the tube's part of it: the
responses Phi(t, s) Gamma G(s) to a deviation within the tube, kept in blocks of
:data:`TUBE_BLOCK_SAMPLES` steps and propagated, and gamma(t), the sum of their norms.
Dimensionless gains; n states.

Stepped in spans of L ~ sqrt(K) steps (a multiple of the block): every span from rest side by
side, with the products Phi_j ... Phi_0 within it; then the spans one after the other, each adding
its products times the state (and the earlier blocks) entering it. ~3 sqrt(K) Python-level steps
instead of K; products of the loop's own matrices only, so the numbers are those of stepping
sample by sample up to rounding (~1e-15 relative, tests/physics/test_hover_loop.py)."""

from __future__ import annotations

import math

import numpy as np

TUBE_BLOCK_SAMPLES = 5
"""Samples whose tube input is propagated as one block (the bound's
integral is taken over blocks of this many steps: exact within a block for inputs of one
direction), -."""


def stepped_response(
    maps: np.ndarray, which: np.ndarray, drive: np.ndarray, tube_in: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """x[k+1] = Phi_k x[k] + w_k from x[0] = 0 over S steps (Phi_k = ``maps[which[k]]``, ``maps``
    (U, n, n), ``which`` (S,); ``drive`` w (S, n)), and the tube's blocks: step k adds ``tube_in``
    (S, n, 3) to the block of steps [5 (k // 5), 5 (k // 5) + 5), every block propagated by the Phi
    of the later steps. Returns (C x (S + 1, 3) (row 0: rest), gamma (S + 1,) (the sum over the
    blocks begun of ||C block||_F), x[S] (n,), the blocks at S (n, 3 B), those with any input, in
    order)."""
    steps, n = drive.shape
    out_y = np.zeros((steps + 1, 3))
    out_g = np.zeros(steps + 1)
    if steps == 0:
        return out_y, out_g, np.zeros(n), np.zeros((n, 0))
    span = TUBE_BLOCK_SAMPLES * max(1, math.ceil(math.sqrt(steps) / TUBE_BLOCK_SAMPLES))  # L
    spans = -(-steps // span)
    per = span // TUBE_BLOCK_SAMPLES  # blocks per span
    pad = spans * span - steps  # identity steps without input after the end: they change nothing
    # step j of every span side by side (contiguous): (span, spans, ...)
    table = np.concatenate([maps, np.eye(n)[None]])
    index = np.concatenate([np.asarray(which, dtype=np.intp), np.full(pad, maps.shape[0])])
    phi_p = table[index.reshape(spans, span).T]
    w_p = np.concatenate([drive, np.zeros((pad, n))]).reshape(spans, span, n).swapaxes(0, 1)[..., None]
    t_p = np.concatenate([tube_in, np.zeros((pad, n, 3))]).reshape(spans, span, n, 3)
    has: np.ndarray = np.any(t_p.reshape(spans, per, TUBE_BLOCK_SAMPLES, n * 3), axis=(2, 3))  # block with input
    t_p = t_p.swapaxes(0, 1)
    # every span from rest, side by side: products Phi_j ... Phi_0, the drive's and the blocks' states
    prod = np.empty((span, spans, n, n))
    free = np.empty((span, spans, n))  # x_j from rest
    own_g = np.zeros((spans, span))  # the span's own blocks' gamma
    p = np.broadcast_to(np.eye(n), (spans, n, n))
    x = np.zeros((spans, n, 1))
    live = np.flatnonzero(has.any(axis=1))  # spans with tube input
    blk = np.zeros((live.size, n, 3 * per))  # their blocks, propagated
    for j in range(span):
        p = np.matmul(phi_p[j], p, out=prod[j])
        x = phi_p[j] @ x + w_p[j]
        free[j] = x[:, :, 0]
        if live.size:
            q = j // TUBE_BLOCK_SAMPLES
            blk[:, :, : 3 * (q + 1)] = phi_p[j, live] @ blk[:, :, : 3 * (q + 1)]
            blk[:, :, 3 * q : 3 * q + 3] += t_p[j, live]
            cb = (c @ blk[:, :, : 3 * (q + 1)]).reshape(live.size, 3, q + 1, 3)
            own_g[live, j] = np.sqrt(np.einsum("sibj,sibj->sb", cb, cb)).sum(axis=1)
    prod = prod.swapaxes(0, 1)  # (spans, span, n, n)
    cprod = c @ prod  # (spans, span, 3, n): C Phi_j ... Phi_0
    free = free.swapaxes(0, 1)
    free_y = free @ c.T
    x_end_rest = free[:, -1]  # each span's last state from rest
    blocks = np.zeros((spans, n, 3 * per))
    blocks[live] = blk
    # the spans in order: the state and the earlier blocks entering each
    x_in = np.zeros(n)
    carried = np.zeros((n, 0))
    for s in range(spans):
        rows = slice(1 + s * span, min(1 + (s + 1) * span, steps + 1))
        m = rows.stop - rows.start
        out_y[rows] = cprod[s, :m] @ x_in + free_y[s, :m]
        g = own_g[s, :m]
        if carried.shape[1]:
            cc = (cprod[s, :m].reshape(m * 3, n) @ carried).reshape(m, 3, -1, 3)  # one product
            g = g + np.sqrt(np.einsum("libj,libj->lb", cc, cc)).sum(axis=1)  # (squares summed in one pass)
        out_g[rows] = g
        x_in = prod[s, -1] @ x_in + x_end_rest[s]
        mine = blocks[s].reshape(n, per, 3)[:, has[s]].reshape(n, -1)
        carried = np.concatenate([prod[s, -1] @ carried, mine], axis=1)
    return out_y, out_g, x_in, carried
