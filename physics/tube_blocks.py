"""The tube's part of the hover loop's response along a plan (:func:`proxplan.physics.hover_loop.
jet_response`): the responses Phi(t, s) Gamma G(s) to a deviation within the tube, kept in blocks
of steps and propagated, and gamma(t), the sum of their norms. Dimensionless gains; n states."""

from __future__ import annotations

import numpy as np

TUBE_BLOCK_SAMPLES = 5
"""Samples whose tube input is propagated as one block (the bound's
integral is taken over blocks of this many steps: exact within a block for inputs of one
direction), -."""


class TubeBlocks:
    """The tube's responses Phi(t, s) Gamma G(s) (n x 3 each), summed over blocks of
    :data:`TUBE_BLOCK_SAMPLES` steps, propagated to now."""

    def __init__(self, c: np.ndarray):
        self.c = c
        n = c.shape[1]
        self.pending = np.zeros((n, 3))
        self.n_pending = 0
        self.blocks = np.zeros((n, 0))

    def step(self, phi: np.ndarray, new: np.ndarray) -> None:
        """Propagate every block by ``phi`` (n, n) and add this step's input response ``new`` (n, 3)."""
        if self.blocks.shape[1]:
            self.blocks = phi @ self.blocks
        self.pending = phi @ self.pending + new
        self.n_pending += 1
        if self.n_pending == TUBE_BLOCK_SAMPLES:
            self.flush()

    def flush(self) -> None:
        """Close the pending block."""
        if np.any(self.pending):
            self.blocks = np.concatenate([self.blocks, self.pending], axis=1)
        self.pending = np.zeros_like(self.pending)
        self.n_pending = 0

    def gain(self) -> float:
        """gamma now: the sum over the blocks (the pending one included) of ||C block||_F."""
        out = float(np.linalg.norm(self.c @ self.pending))
        return out + (_block_norms(self.c, self.blocks) if self.blocks.shape[1] else 0.0)


def _block_norms(c: np.ndarray, blocks: np.ndarray) -> float:
    """Sum over the blocks (columns of 3) of ||C block||_F."""
    out = (c @ blocks).reshape(3, -1, 3)
    return float(np.sqrt((out**2).sum(axis=(0, 2))).sum())
