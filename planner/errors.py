"""Planning failures that are results, not user mistakes (the CLI exits 1 naming vehicle and constraint)."""

from __future__ import annotations


class InfeasibleError(Exception):
    """No plan: ``vehicle`` could not meet ``constraint`` (e.g. "downwash of carrier")."""

    def __init__(self, vehicle: str, constraint: str, message: str, details: dict | None = None):
        super().__init__(message)
        self.vehicle = vehicle
        self.constraint = constraint
        self.message = message
        # machine-readable diagnosis for ``--json`` (e.g. the source vehicle, by how much, a
        # suggested goal); plain JSON types only
        self.details = dict(details or {})


class PlanNotFound(Exception):
    """A search gave up (its count budget or the wall-clock budget ran out) without a plan. This
    proves nothing about feasibility; the CLI says "not found within ..." and exits 3, never
    "infeasible"."""

    def __init__(self, message: str, *, vehicles: list[str] | None = None, details: dict | None = None):
        super().__init__(message)
        self.message = message
        self.vehicles = list(vehicles or [])
        self.details = dict(details or {})
