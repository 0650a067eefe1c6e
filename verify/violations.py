"""A violated check, and merging consecutive violating samples into one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Violation:
    """One violated check: from ``t_s`` (s, plan sample ``sample``) on, ``vehicle`` broke ``kind``
    (worst ``value`` against ``limit``; units in ``detail``)."""

    t_s: float
    vehicle: str
    kind: str
    detail: str
    value: float
    limit: float
    sample: int | None = None  # index into the plan's time grid where it starts

    def __str__(self) -> str:
        at = f"t={self.t_s:.2f}s" + (f" (sample {self.sample})" if self.sample is not None else "")
        return f"{at} {self.vehicle}: {self.kind}: {self.detail} ({self.value:.4g} > limit {self.limit:.4g})"

    def to_dict(self) -> dict:
        return {
            "t_s": self.t_s,
            "sample": self.sample,
            "vehicle": self.vehicle,
            "kind": self.kind,
            "detail": self.detail,
            "value": self.value,
            "limit": self.limit,
        }


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of True in ``mask`` (N,)."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]])
    return list(zip(starts.tolist(), ends.tolist()))


def add_runs(
    out: list[Violation],
    t_s: np.ndarray,
    mask: np.ndarray,
    value: np.ndarray,
    limit: float,
    vehicle: str,
    kind: str,
    detail: str,
    *,
    plan_t_s: np.ndarray,
) -> None:
    """Append one :class:`Violation` per run of ``mask`` on times ``t_s`` (worst ``value`` of the
    run); ``plan_t_s`` is the plan grid the reported sample index refers to."""
    for s, e in runs(mask):
        worst = float(np.max(value[s : e + 1]))
        sample = int(np.clip(np.searchsorted(plan_t_s, t_s[s] + 1e-9, side="right") - 1, 0, plan_t_s.size - 1))
        out.append(
            Violation(float(t_s[s]), vehicle, kind, f"{detail} (until t={t_s[e]:.2f}s)", worst, float(limit), sample)
        )
