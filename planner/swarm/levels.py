"""Levels of their own per vehicle type: heights at which the vehicles of one group of types never
conflict with those of another, whatever their horizontal positions.

World frame, z up, m. The keep-out of an ordered pair of types (:class:`~proxplan.planner.swarm.keepout.KeepOut`,
d = p_b - p_a) holds no point at a height difference d_z once d_z is beyond the cut-off's reach of
the vehicle above on the one below (and beyond the separation sphere): then the two can cross
over each other. That height differs a lot by pair (the built-in types: a Crazyflie 0.38 m above a
small quad, a small quad 5.4 m above a Crazyflie), so where the free box is tall enough, the types
can be stacked: each group of types on a level of its own, every pair of levels far enough apart
for every pair of types on them. Then the levels are independent planar problems, each with a
fraction of the vehicles, joined by vertical moves at the start and at the end.

:func:`free_height_m` is the least height of b above a from which the pair never conflicts (the
keep-out's horizontal radius zero over every larger difference inside the box, moving, with the
tube), :func:`stack_levels` the stack of type groups that fits the box with the most levels
(fewest vehicles on the busiest level; ties: the least vertical travel), every ordered partition of
the types into groups tried (a handful of types: 13 stacks for 3).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from proxplan.planner.swarm.keepout import KeepOut, keepout_for
from proxplan.planner.swarm.problem import GROWTH_M, SwarmProblem

# heights are searched to this resolution (m): the cut-off tables' dz step is 2 cm
HEIGHT_RESOLUTION_M = 0.001
# levels are stacked where each pair's cut-off at this share of the authority fraction vanishes. Set
# watching grid-64 and corridor-64 (issue 37 round 14A), not derived. What it covers, measured (stop 53
# round 15A, benchmarks/bench_level_margins.py on the bench's grid-64 types): at share 1 the stacks
# fail verify by 1-13 %, not by one source (the verifier's usage of one source at a pair's free height,
# the target moved by its tube: 0.028-0.094 of 0.1) but by the sum of 2-4 vehicles of the level above
# (the verifier sums the jets); the densest arrangement the keep-outs allow a level (a hexagonal lattice
# at 0.30 m) keeps that sum within the fraction only up to 0.66 m below Parrots (the sum grows with the
# gap: the jets widen and overlap), and there a vehicle riding under another is deflected 8.4-14.1 cm by the
# verifier's loop in the jet (2.1-2.6 cm at 1.16 m; 2.4 cm in the keep-outs): for the built-in types no gap
# is free of both a priori. At 0.5 the small quads fly 1.16 m below the others: two sources fit.
STACK_AUTHORITY_SHARE = 0.5


def free_height_m(ko: KeepOut, span_m: float) -> float | None:
    """Least d_z >= 0 (m) such that the pair of ``ko`` (b above a by d_z' in [d_z, ``span_m``])
    never conflicts while moving, or None when even ``span_m`` is not free. Bisection on
    :meth:`KeepOut.horizontal_radius_m` over the band [d_z, span]: the band shrinks as d_z grows, so
    the radius over it cannot grow."""
    if ko.horizontal_radius_m(span_m, span_m) > 0.0:
        return None
    lo, hi = 0.0, span_m
    if ko.horizontal_radius_m(lo, span_m) <= 0.0:
        return 0.0
    while hi - lo > HEIGHT_RESOLUTION_M:
        mid = 0.5 * (lo + hi)
        if ko.horizontal_radius_m(mid, span_m) > 0.0:
            lo = mid
        else:
            hi = mid
    return hi


@dataclass(frozen=True)
class Levels:
    """Each agent's level (m) and the groups of types, bottom to top."""

    groups: tuple[tuple[int, ...], ...]  # type indices per level, bottom first
    heights_m: tuple[float, ...]  # height of each level, m
    agent_z_m: np.ndarray  # (A,) the level of each agent, m
    # (lowest, highest) height each level's plan may fly at, m (:func:`level_bands_m`); None: its height only
    bands_m: tuple[tuple[float, float], ...] | None = None

    def band_m(self, k: int) -> tuple[float, float]:
        """(lowest, highest) height level ``k``'s plan may fly at, m."""
        z = self.heights_m[k]
        return (z, z) if self.bands_m is None else self.bands_m[k]


def level_bands_m(heights_m: tuple[float, ...], lo_z_m: float, hi_z_m: float) -> tuple[tuple[float, float], ...]:
    """Per level (bottom first) the heights its vehicles may fly at without meeting another level's, m: the
    bottom level down to the free box's floor ``lo_z_m``, the top level up to its ceiling ``hi_z_m``, every
    other level its own height only. Exact from :func:`free_height_m`: a pair free at a height difference
    d_z is free at every larger one inside the box, and flying down from the bottom level (up from the top)
    only widens its differences to every other level; a middle level moving would narrow one of them (round
    27A: the top level's vehicles pass over the rows of starts and goals that wall a single height)."""
    n = len(heights_m)
    return tuple((lo_z_m if k == 0 else z, hi_z_m if k == n - 1 else z) for k, z in enumerate(heights_m))


def _ordered_partitions(items: list[int]):
    """Every ordered partition of ``items`` into non-empty groups."""
    n = len(items)
    for labels in itertools.product(range(n), repeat=n):
        used = sorted(set(labels))
        if used != list(range(len(used))):
            continue
        yield tuple(tuple(x for x, lab in zip(items, labels) if lab == g) for g in range(len(used)))


def stacking_keepouts(
    problem: SwarmProblem, limits, field_form: str | None, effects: tuple
) -> dict[tuple[int, int], KeepOut]:
    """The keep-outs of ``problem``'s type pairs at :data:`STACK_AUTHORITY_SHARE` of the scenario's
    authority fraction (``limits``, ``field_form``, ``effects``: the scenario's, as
    :func:`proxplan.planner.swarm.problem.swarm_problem` builds them), grown as the problem's are
    (the same tube, sampling growth and tracking / deflection growth): the levels are stacked on these."""
    strict = replace(limits, authority_fraction=STACK_AUTHORITY_SHARE * limits.authority_fraction)
    out = {}
    for (a, b), ko in problem.keepouts.items():
        out[(a, b)] = keepout_for(
            problem.vehicles[a],
            problem.vehicles[b],
            limits=strict,
            field_form=field_form,
            effects=effects,
            sample_m=GROWTH_M,
            deflection_m=ko.deflection_m,
            rest_deflection_m=ko.w_rest_m,
            undamped_level=limits.authority_fraction,
        )
    return out


def stack_levels(problem: SwarmProblem, keepouts: dict[tuple[int, int], KeepOut] | None = None) -> Levels | None:
    """The stack of type groups with the most levels that fits the free box (see module), placed to
    move the vehicles least, or None when no stack of two levels or more fits; the levels' heights
    from ``keepouts`` (:func:`stacking_keepouts`; None: the problem's own)."""
    keepouts = problem.keepouts if keepouts is None else keepouts
    types = sorted({int(t) for t in problem.type_index})
    lo_z, hi_z = float(problem.lo_m[2]), float(problem.hi_m[2])
    span = hi_z - lo_z
    free = {}
    for a in types:
        for b in types:
            free[(a, b)] = free_height_m(keepouts[(a, b)], span)  # b above a
    tz = np.asarray(problem.type_index)
    best = None
    for groups in _ordered_partitions(types):
        if len(groups) < 2:
            continue
        rel = [0.0]
        ok = True
        for k in range(1, len(groups)):
            need = 0.0
            for i in range(k):
                for a in groups[i]:
                    for b in groups[k]:
                        f = free[(a, b)]
                        if f is None:
                            ok = False
                        else:
                            need = max(need, rel[i] + f)
            rel.append(need)
        if not ok or rel[-1] > span:
            continue
        # place the stack in the box: the offset that moves the vehicles least (largest vertical move)
        level_of_type = {t: k for k, g in enumerate(groups) for t in g}
        rel_agent = np.array([rel[level_of_type[int(t)]] for t in tz])
        ends = np.concatenate([problem.starts_m[:, 2], problem.goals_m[:, 2]])
        rel2 = np.concatenate([rel_agent, rel_agent])
        offsets = np.arange(lo_z, hi_z - rel[-1] + 1e-9, 0.01)
        moves = np.abs(ends[None, :] - (offsets[:, None] + rel2[None, :])).max(axis=1)
        j = int(np.argmin(moves))
        busiest = max(int(np.isin(tz, g).sum()) for g in groups)
        score = (busiest, float(moves[j]))
        if best is None or score < best[0]:
            best = (score, groups, tuple(float(offsets[j] + r) for r in rel), offsets[j] + rel_agent)
    if best is None:
        return None
    _, groups, heights, agent_z = best
    return Levels(
        groups=groups,
        heights_m=heights,
        agent_z_m=np.asarray(agent_z, dtype=float),
        bands_m=level_bands_m(heights, lo_z, hi_z),
    )


def levelled_endpoints(problem: SwarmProblem, levels: Levels) -> tuple[np.ndarray, np.ndarray]:
    """(starts, goals) (A, 3) m: each agent's start and goal moved straight up or down to its level."""
    starts, goals = problem.starts_m.copy(), problem.goals_m.copy()
    starts[:, 2] = levels.agent_z_m
    goals[:, 2] = levels.agent_z_m
    return starts, goals


def transition_steps(
    conflict: Callable[[int, int, int, int, int, int], bool], q_from: tuple[int, ...], q_to: tuple[int, ...]
) -> list[tuple[int, ...]] | None:
    """Configurations after ``q_from`` that take every agent to its vertex of ``q_to`` in steps that
    pass the synchronous test ``conflict`` (:meth:`SyncTable.conflict`) for every pair: each step
    moves, in agent order, every agent whose move conflicts with no move taken into the step and with
    no agent resting; None when some agents are left that none can move (a count: at most one step
    per agent)."""
    cur = list(q_from)
    out: list[tuple[int, ...]] = []
    left = [a for a in range(len(cur)) if cur[a] != q_to[a]]
    while left:
        nxt = list(cur)
        moved: list[int] = []
        for a in left:
            nxt[a] = q_to[a]
            if any(conflict(a, cur[a], nxt[a], b, cur[b], nxt[b]) for b in range(len(cur)) if b != a):
                nxt[a] = cur[a]
            else:
                moved.append(a)
        if not moved:
            return None
        out.append(tuple(nxt))
        cur = nxt
        left = [a for a in left if cur[a] != q_to[a]]
    return out
