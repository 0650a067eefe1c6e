"""From a coordination plan to trajectories: each step's moves flown together, a group of them as
soon as the moves it must follow have ended (an action dependency graph).

Step k of the plan (configurations Q_{k-1} -> Q_k, :mod:`proxplan.planner.swarm.lacam`) is split
into **groups**: the connected components of "come within reach" among its moves (two moves come
within reach when the horizontal distance between their segments is below the largest horizontal
reach of any keep-out, :attr:`SwarmProblem.reach_xy_m`, grown by :data:`REACH_GROWTH_M`, and their
heights are within the largest vertical reach). A group's vehicles fly their straight moves along
one common rest-to-rest profile (its longest move at its vehicles' common limits,
:func:`proxplan.planner.timing.profile.rest_to_rest`), so the relative position of any two of them
runs on the straight segment the synchronous test checked (:mod:`proxplan.planner.swarm.sync`). A
group starts when every group of an earlier step that comes within reach of it has ended (its own
vehicles' previous moves among them: they share an endpoint), not when the whole previous step has
ended: the execution of a MAPF plan by its temporal dependencies (Hönig et al. 2016, "Multi-agent
path finding with kinematic constraints", MAPF-POST). ``dependencies=False`` gives plain lock-step
(every step starts when the previous one has ended, one profile per step).

Why the trajectories stay conflict-free: take a group G of step k and a vehicle b not in it. b's
moves that come within reach of G end before G starts (earlier steps) or start after G ends (later
steps, which depend on G); so while G flies, b is on a move that never comes within reach of G, or
at rest at the end of a move (or at its start) that is within reach of G only if its next move is
as well, which is then of a later step: b rests where it rested in step k of the plan, a relative
position the synchronous test checked against G's moves. Groups of one step never come within
reach of each other. So every pair within reach meets in a relative state of the plan, at every
speed and type mix. Never later than lock-step (by induction over the steps: a group starts no
later than its step in lock-step and its profile is for a move no longer than the step's longest,
at limits no smaller than the step's least), tested. This is the guaranteed conversion;
:mod:`proxplan.planner.swarm.retime` then shortens it in continuous time.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from proxplan.planner.swarm.lattice import Lattice
from proxplan.planner.swarm.occupancy import SAMPLING_GROWTH_M
from proxplan.planner.swarm.problem import GROWTH_M, SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.profile import LineMove, rest_to_rest

__all__ = ["REACH_GROWTH_M", "lockstep_tracks", "lockstep_tracks_at", "segment_distance_xy_m"]

# "within reach" uses the keep-outs' largest reach grown by what the two exact tests add: the
# synchronous table's whole-millimetre growth and the occupancy's growth between grid samples, m
# (a larger value only adds dependencies: a later plan, never a less safe one)
REACH_GROWTH_M = GROWTH_M + SAMPLING_GROWTH_M


def segment_distance_xy_m(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Smallest horizontal distance between segments p0-p1 and q0-q1 (broadcast arrays (..., >= 2),
    m): zero where they cross, else the least of the four endpoint-to-segment distances."""
    p0, p1, q0, q1 = (np.asarray(x, dtype=float)[..., :2] for x in (p0, p1, q0, q1))

    def point_seg(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        e = b - a
        ee = np.einsum("...i,...i->...", e, e)
        safe = np.where(ee > 0.0, ee, 1.0)
        t = np.clip(np.where(ee > 0.0, np.einsum("...i,...i->...", x - a, e) / safe, 0.0), 0.0, 1.0)
        return np.linalg.norm(x - (a + t[..., None] * e), axis=-1)

    def cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])

    crossing = (cross(q0, q1, p0) * cross(q0, q1, p1) < 0.0) & (cross(p0, p1, q0) * cross(p0, p1, q1) < 0.0)
    d = np.minimum(
        np.minimum(point_seg(p0, q0, q1), point_seg(p1, q0, q1)),
        np.minimum(point_seg(q0, p0, p1), point_seg(q1, p0, p1)),
    )
    return np.where(crossing, 0.0, d)


# exact segment distances are computed this many candidate pairs at a time (bounds the temporaries'
# memory to a few hundred MB, whatever the plan's size)
PAIR_CHUNK = 1 << 20


def _pair_radius_m(problem, ti: np.ndarray, tj: np.ndarray, dz_lo: np.ndarray, dz_hi: np.ndarray) -> np.ndarray:
    """(P,) largest horizontal distance at which agents of types ``ti`` and ``tj`` conflict while
    moving at some height difference z_j - z_i in [dz_lo, dz_hi] (m; both orders of the pair's
    keep-out, :meth:`KeepOut.horizontal_radius_m`), computed once per distinct (types, band)."""
    # the distinct rows by one integer key of the columns' distinct values (a sort of P integers, not of
    # P rows of four floats: round 29B; the same radius per pair)
    key = np.zeros(np.shape(ti), dtype=np.int64)
    for col in (ti, tj, dz_lo, dz_hi):
        values, idx = np.unique(col, return_inverse=True)
        key = key * len(values) + np.asarray(idx).reshape(-1)
    uniq_key, first, inv = np.unique(key, return_index=True, return_inverse=True)
    out = np.empty(uniq_key.shape[0])
    for k, m in enumerate(first.tolist()):
        a, b, lo, hi = int(ti[m]), int(tj[m]), float(dz_lo[m]), float(dz_hi[m])
        ab = problem.keepouts[(a, b)].horizontal_radius_m(lo, hi)
        ba = problem.keepouts[(b, a)].horizontal_radius_m(-hi, -lo)
        out[k] = max(ab, ba)
    return out[np.asarray(inv).reshape(-1)]


def _near_pairs(problem: SwarmProblem, p0: np.ndarray, p1: np.ndarray, types: np.ndarray) -> np.ndarray:
    """(P, 2) pairs i < j of moves (segments p0 -> p1, of agents of ``types``) that come within reach
    of each other: candidates from a k-d tree of the segments' midpoints (two segments within reach
    have midpoints within the reach plus half of each length), then the exact segment distance on
    those alone, against the largest reach of any pair (horizontal and vertical) and then against
    the reach of the two agents' types over the height differences their moves can have
    (:func:`_pair_radius_m`): vehicles on levels far enough apart for their types never depend on
    each other."""
    reach = problem.reach_xy_m + REACH_GROWTH_M
    half = 0.5 * np.linalg.norm((p1 - p0)[:, :2], axis=1)
    mid = 0.5 * (p0 + p1)[:, :2]
    cand = cKDTree(mid).query_pairs(reach + 2.0 * float(half.max()), output_type="ndarray")
    zlo, zhi = np.minimum(p0[:, 2], p1[:, 2]), np.maximum(p0[:, 2], p1[:, 2])
    keep = []
    for c in range(0, cand.shape[0], PAIR_CHUNK):
        i, j = cand[c : c + PAIR_CHUNK, 0], cand[c : c + PAIR_CHUNK, 1]
        # two cheap necessary conditions first (round 29B, the same pairs): every point of a segment lies
        # within half its length of its midpoint, so segments within ``reach`` have midpoints within
        # ``reach`` plus both halves; and the height bands within the vertical reach
        ok = np.hypot(*(mid[i] - mid[j]).T) < reach + half[i] + half[j]
        ok &= np.maximum(zlo[i] - zhi[j], zlo[j] - zhi[i]) < problem.reach_z_m + REACH_GROWTH_M
        sel = np.flatnonzero(ok)
        i, j = i[sel], j[sel]
        d = segment_distance_xy_m(p0[i], p1[i], p0[j], p1[j])
        near = d < reach
        sel, i, j, d = sel[near], i[near], j[near], d[near]
        radius = _pair_radius_m(problem, types[i], types[j], zlo[j] - zhi[i], zhi[j] - zlo[i]) + REACH_GROWTH_M
        keep.append(cand[c : c + PAIR_CHUNK][sel[d < radius]])
    return np.sort(np.concatenate(keep), axis=1) if keep else np.zeros((0, 2), dtype=np.int64)


def _start_steps(
    problem: SwarmProblem, step: np.ndarray, agent: np.ndarray, p0: np.ndarray, p1: np.ndarray, dependencies: bool
):
    """(label (M,): each move's group, named by its first move; start (M,) and profiles per group)."""
    M = step.size
    if dependencies:
        pairs = _near_pairs(problem, p0, p1, np.asarray(problem.type_index)[agent])
        same = step[pairs[:, 0]] == step[pairs[:, 1]]
        _, comp = connected_components(
            coo_matrix((np.ones(int(same.sum())), (pairs[same, 0], pairs[same, 1])), shape=(M, M)), directed=False
        )
        first = np.full(comp.max() + 1, M)
        np.minimum.at(first, comp, np.arange(M))
        label = first[comp]
        cross = pairs[~same]  # (earlier, later): pairs are i < j and moves are in step order
    else:  # lock-step: one group per step, after the previous one
        label = np.searchsorted(step, step)
        cross = np.zeros((0, 2), dtype=np.int64)
    cross = cross[np.argsort(step[cross[:, 1]], kind="stable")]
    bounds = np.searchsorted(step[cross[:, 1]], np.arange(int(step.max()) + 2))
    end = np.zeros(M, dtype=np.int64)  # by group label
    start = np.zeros(M, dtype=np.int64)
    profiles = {}
    last = 0
    for k in np.unique(step).tolist():
        here = cross[bounds[k] : bounds[k + 1]]
        wait = np.zeros(M, dtype=np.int64)
        np.maximum.at(wait, label[here[:, 1]], end[label[here[:, 0]]])
        for g in np.unique(label[step == k]).tolist():
            members = np.flatnonzero(label == g)
            lengths = np.linalg.norm(p1[members] - p0[members], axis=1)
            profile = rest_to_rest(float(lengths.max()), problem.common_limits(agent[members].tolist()), GRID_DT_S)
            t0 = int(wait[g]) if dependencies else last
            start[g], end[g], profiles[g] = t0, t0 + profile.steps, profile
            last = int(end[g])
    return label, start, profiles


def lockstep_tracks(
    lattice: Lattice, configurations: list[tuple[int, ...]], *, dependencies: bool = True
) -> list[GridTrack]:
    """One :class:`GridTrack` per agent flying ``configurations`` of ``lattice`` (see module)."""
    return lockstep_tracks_at(lattice.problem, lattice.pos_m, configurations, dependencies=dependencies)


def lockstep_tracks_at(
    problem: SwarmProblem, pos_m: np.ndarray, configurations: list[tuple[int, ...]], *, dependencies: bool = True
) -> list[GridTrack]:
    """:func:`lockstep_tracks` for configurations of indices into any points ``pos_m`` (V, 3), m (every
    step must pass the synchronous test on them)."""
    pos = np.asarray(pos_m, dtype=float)
    A = problem.n_agents
    step_l, agent_l, u_l, v_l = [], [], [], []
    for k in range(1, len(configurations)):
        u = np.asarray(configurations[k - 1])
        v = np.asarray(configurations[k])
        for a in np.flatnonzero(u != v).tolist():
            step_l.append(k)
            agent_l.append(a)
            u_l.append(int(u[a]))
            v_l.append(int(v[a]))
    moves: list[list[tuple[int, LineMove]]] = [[] for _ in range(A)]
    if step_l:
        step, agent = np.asarray(step_l), np.asarray(agent_l)
        p0, p1 = pos[np.asarray(u_l)], pos[np.asarray(v_l)]
        label, start, profiles = _start_steps(problem, step, agent, p0, p1, dependencies)
        for m in range(step.size):
            g = int(label[m])
            moves[int(agent[m])].append((int(start[g]), LineMove(p0[m], p1[m], profiles[g])))
    return [
        GridTrack(a, int(problem.type_index[a]), pos[configurations[0][a]], sorted(moves[a], key=lambda x: x[0]))
        for a in range(A)
    ]
