"""How far a goal is from the keep-out it breaks, and how far that keep-out reaches at rest and grown by the
tracking tube (:func:`pair_need`): the figures :func:`proxplan.planner.checks.precheck.check_goal_tubes` names in
its error."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.checks.constraints import Track, build_checker

__all__ = ["PairNeed", "pair_need"]


@dataclass(frozen=True)
class PairNeed:
    """How far a goal lies from another vehicle's final position and how far the keep-out it breaks
    reaches there: at rest, and grown by the tracking tube (the verifier's rule while either moves), m.
    ``lateral``: the keep-out is a downwash cut-off (horizontal distances at ``dz_m``); else the
    separation sphere (3-D distance) or the keep-out ellipsoid (radius against the distance with its
    vertical part divided by 3, the ellipsoid's 3 r semi-axis)."""

    lateral: bool
    distance_m: float  # horizontal (lateral) or 3-D distance between the two points, m
    dz_m: float  # height of the other vehicle above this one (negative: below), m
    rest_m: float  # the keep-out's reach at rest, m
    tube_m: float  # grown by the tracking tube (what the verifier applies while either moves), m

    def text(self, other: str) -> str:
        if self.lateral:
            side = "below" if self.dz_m > 0 else "above"
            what = f"{self.distance_m:.3f} m to the side of {other}'s final position, {abs(self.dz_m):.3f} m {side} it"
        else:
            what = f"{self.distance_m:.3f} m from {other}'s final position"
        return (
            f"it is {what}; the pair needs {self.tube_m:.3f} m ({self.rest_m:.3f} m at rest), "
            f"{self.tube_m - self.distance_m:.3f} m more"
        )

    def details(self) -> dict:
        return {
            "distance_m": round(self.distance_m, 6),
            "distance_is_lateral": self.lateral,
            "dz_m": round(self.dz_m, 6),
            "needed_m": round(self.tube_m, 6),
            "needed_at_rest_m": round(self.rest_m, 6),
        }


def pair_need(
    scenario: Scenario,
    name: str,
    other: str,
    bad: str,
    goal_m: np.ndarray,
    other_m: np.ndarray,
    *,
    mode: str,
) -> PairNeed:
    """:class:`PairNeed` of ``name``'s goal against vehicle ``other`` of ``bad`` (the constraint
    :func:`check_goal_tubes` found broken) resting at ``other_m``, from the same :func:`build_checker`
    rules: a downwash cut-off at the pair's height difference, else the separation (or ellipsoid) radius."""
    track = Track.static(other, scenario.vehicles[other].vehicle, np.asarray(other_m, dtype=float))
    rel = np.asarray(other_m, dtype=float) - np.asarray(goal_m, dtype=float)
    dz = float(rel[2])
    lateral = bad.startswith("downwash")
    reach = []
    for tube in (False, True):
        rule = build_checker(scenario, name, [track], mode=mode, tube=tube).rules[0]
        if lateral:
            table = rule.cut_from_other if bad.startswith("downwash of") else rule.cut_on_other
            reach.append(0.0 if table is None else rule.cutoff_m(table, abs(dz)))
        else:
            reach.append(rule.separation_m if rule.ellipsoid_r_m is None else rule.ellipsoid_r_m)
    if lateral:
        dist = float(np.hypot(rel[0], rel[1]))
    elif bad.startswith("ellipsoid"):  # the ellipsoid's semi-axis is 3 r vertically: its scaled distance
        dist = float(np.sqrt(rel[0] ** 2 + rel[1] ** 2 + (rel[2] / 3.0) ** 2))
    else:
        dist = float(np.linalg.norm(rel))
    return PairNeed(lateral, dist, dz, reach[0], reach[1])
