"""Space-time search of one vehicle on the shared roadmap (:mod:`proxplan.planner.swarm.roadmap`) with waits.

Time is split into windows of ``window_s``; every vehicle starts at rest at its start at window 0.
A vehicle either waits at a node (occupying its atom for one window) or flies a *run*: a straight
jerk-limited rest-to-rest Ruckig motion (:func:`proxplan.planner.timing.ruckig_segment`, the motion
that is flown later) along one lattice axis over m unit edges, or an access edge between a start /
goal and a lattice vertex. A run lasting T s occupies ceil(T / window_s) windows; in window j it
occupies the unit edges it sweeps in [j, j + 1) window_s (from its exact Ruckig profile), so the
per-window swept atoms cover the continuous motion whatever its timing inside the window. After its
last run a vehicle holds its goal for ever.

Two vehicles conflict when, in one window, an atom of one is in the conflict set of an atom of the
other (a goal held from window A conflicts with anything in its set from A on).

The single-vehicle search (:class:`Search`; the multi-agent layer is :mod:`proxplan.planner.swarm.pbs`):
space-time weighted A* (``weight``; 1 is plain A*) for one vehicle against the reservations of a set
of vehicles (cost = arrival window; heuristic = rest-to-rest time of the horizontal plus that of the
vertical distance to the goal's access vertex, plus the access time, admissible because runs are
straight and rest-to-rest and the rest-to-rest time is subadditive). Run kinds: the lattice's
``DIRECTIONS`` both ways; lengths 1..3 edges, the longest free run, and lengths ending level with the
goal. Vehicles neither above nor planned are treated as parked at their starts until their current
first run has taken them away. Deterministic: ties broken by larger g, then insertion order; a cap
on expansions (a count). The search also answers the first conflict between two paths.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.swarm.roadmap import DIRECTIONS, Roadmap
from proxplan.planner.swarm.runs import INF_WINDOW, Agent, Move, Path, Profiles
from proxplan.planner.timing.durations import duration_table


class Search:
    """Shared data of one multi-agent search (roadmap, agents, profiles, heuristics)."""

    def __init__(
        self, rm: Roadmap, agents: list[Agent], window_s: float, *, max_expansions: int = 40000, weight: float = 1.0
    ):
        self.rm = rm
        self.weight = weight  # heuristic inflation: each single-vehicle path <= weight x its optimum
        self.agents = agents
        self.window_s = window_s
        self.max_expansions = max_expansions
        self.profiles = Profiles(window_s)
        self.nv = rm.n_vertices
        self.n_atoms = rm.n_atoms
        self.strides = [int(np.prod(rm.shape[a + 1 :])) for a in range(3)]
        # per edge kind: index step, flat stride, edge length (m), longest free run from each vertex
        # in the + and - direction (edges)
        self.kinds = []
        for kind, step in enumerate(DIRECTIONS):
            ok = rm.edge_ok[kind]
            plus = np.zeros(rm.shape, dtype=np.int64)
            minus = np.zeros(rm.shape, dtype=np.int64)
            n_max = max(rm.shape)
            for _ in range(n_max):  # fixed point of run(u) = ok(u) * (1 + run(u + step))
                nxt = _shifted(plus, -step)
                plus = np.where(ok, nxt + 1, 0)
            ok_back = _shifted(ok, step)  # edge arriving at u from u - step
            for _ in range(n_max):
                prv = _shifted(minus, step)
                minus = np.where(ok_back, prv + 1, 0)
            stride = int(np.dot(step, self.strides))
            length = float(np.linalg.norm(step * rm.spacing_m))
            self.kinds.append((kind + 1, step, stride, length, plus.reshape(-1).tolist(), minus.reshape(-1).tolist()))
        self.vertex_ok = rm.vertex_ok.reshape(-1).tolist()
        self.idx = np.stack(np.unravel_index(np.arange(self.nv), rm.shape), axis=-1)
        # access edges by endpoint
        self.access_of: dict[int, list[tuple[int, int]]] = {}
        for k, (e, v) in enumerate(rm.access):
            self.access_of.setdefault(e, []).append((v, k))
        self._h: dict[int, list[float]] = {}
        self._offsets: dict = {}

    # -- geometry helpers ------------------------------------------------------------------------
    def node_pos(self, node: int) -> np.ndarray:
        if node < self.nv:
            return self.rm.position(node)
        return self.rm.endpoints_m[node - self.nv]

    def start_node(self, ag: Agent) -> int:
        v = int(self.rm.endpoint_vertex[ag.start])
        return v if v >= 0 else self.nv + ag.start

    def goal_node(self, ag: Agent) -> int:
        v = int(self.rm.endpoint_vertex[ag.goal])
        return v if v >= 0 else self.nv + ag.goal

    def rest_atom(self, ag: Agent, node: int) -> int:
        """Atom held while at rest at ``node``: the own start / goal endpoint atom there, else the
        lattice vertex atom."""
        if node == self.start_node(ag):
            return self.rm.endpoint_atom(ag.start)
        if node == self.goal_node(ag):
            return self.rm.endpoint_atom(ag.goal)
        if node >= self.nv:
            return self.rm.endpoint_atom(node - self.nv)
        return node

    def goal_targets(self, ag: Agent) -> list[tuple[int, float]]:
        """(lattice vertex, extra time s) from which the goal is reached (0 s when on the lattice)."""
        g = self.goal_node(ag)
        if g < self.nv:
            return [(g, 0.0)]
        out = []
        for v, _k in self.access_of.get(ag.goal, []):
            d = float(np.linalg.norm(self.rm.endpoints_m[ag.goal] - self.rm.position(v)))
            out.append((v, self.profiles.run(ag.limits, d)[0]))
        return out

    def heuristic(self, ag: Agent) -> list[float]:
        """Admissible windows-to-goal per lattice vertex (see module), list of length V."""
        key = id(ag)
        if key in self._h:
            return self._h[key]
        table = duration_table(ag.limits)
        dist = np.arange(len(table.table)) * table.step_m
        dur = np.asarray(table.table)
        best = np.full(self.nv, np.inf)
        for v, extra in self.goal_targets(ag):
            dv = np.abs(self.idx - self.idx[v]) * self.rm.spacing_m  # (V, 3) m
            d_xy = np.hypot(dv[:, 0], dv[:, 1])
            t = np.interp(d_xy, dist, dur) + np.interp(dv[:, 2], dist, dur) + extra
            best = np.minimum(best, t)
        h = (best / self.window_s).tolist()
        self._h[key] = h
        return h

    def lower_bound_windows(self, ag: Agent) -> float:
        """Admissible windows from the agent's start to its goal on the roadmap."""
        h = self.heuristic(ag)
        s = self.start_node(ag)
        if s < self.nv:
            return h[s]
        best = math.inf
        for v, _k in self.access_of.get(ag.start, []):
            d = float(np.linalg.norm(self.rm.endpoints_m[ag.start] - self.rm.position(v)))
            best = min(best, self.profiles.run(ag.limits, d)[0] / self.window_s + h[v])
        return best

    def run_offsets(self, limits: KinematicLimits, kind: int, sgn: int, m: int) -> tuple[float, list[tuple[int, ...]]]:
        """(duration s, per window the atom ids relative to the start vertex) of a run of ``m``
        unit edges of edge ``kind`` (1..) in direction ``sgn``: the unit edges it sweeps in each
        window (cached)."""
        key = (limits, kind, sgn, m)
        hit = self._offsets.get(key)
        if hit is None:
            _k, _step, stride, ell, _p, _m = self.kinds[kind - 1]
            dur, sw = self.profiles.run(limits, m * ell)
            rows = []
            for j in range(len(sw)):
                e_lo = min(int(sw[j, 0] / ell + 1e-9), m - 1)
                e_hi = min(max(int(math.ceil(sw[j, 1] / ell - 1e-9)) - 1, e_lo), m - 1)
                rows.append(
                    tuple(
                        kind * self.nv + (e * stride if sgn > 0 else -(e + 1) * stride) for e in range(e_lo, e_hi + 1)
                    )
                )
            hit = (dur, rows)
            self._offsets[key] = hit
        return hit

    def leave_windows(self, ag: Agent) -> int:
        """Windows a vehicle needs at least to leave its start (its shortest first run), or
        INF_WINDOW when it holds its start (start = goal)."""
        if self.start_node(ag) == self.goal_node(ag):
            return INF_WINDOW
        ell = float(self.rm.spacing_m.min())
        return len(self.profiles.run(ag.limits, ell)[1])

    # -- reservations ----------------------------------------------------------------------------
    def reservation(self, ag: Agent, higher: list[Path], horizon: int, parked: tuple = ()):
        """(blocked flags over window * n_atoms + atom, perm list per atom) for ``ag`` against the
        paths ``higher`` and the agents ``parked`` at their starts for ever."""
        blocked = np.zeros(horizon * self.n_atoms, dtype=np.uint8)
        perm = np.full(self.n_atoms, INF_WINDOW, dtype=np.int64)
        t = ag.type_index
        for item in parked:  # an Agent (parked for ever) or (Agent, until window)
            other, until = (item, INF_WINDOW) if isinstance(item, Agent) else item
            g = self.rm.blocked_by(other.type_index, t, np.array([self.rm.endpoint_atom(other.start)]))
            if until >= INF_WINDOW:
                perm[g] = 0
            else:
                for k in range(min(until, horizon)):
                    blocked[k * self.n_atoms + g] = 1
        for p in higher:
            w, a = self.blocked_of(p, t)
            keep = w < horizon
            blocked[w[keep] * self.n_atoms + a[keep]] = 1
            g = self.rm.blocked_by(self.agent_of_path(p).type_index, t, np.array([p.goal_atom]))
            np.minimum.at(perm, g, p.arrival)
        return blocked, perm.tolist()

    def agent_of_path(self, p: Path) -> Agent:
        return p._agent  # type: ignore[attr-defined]

    def blocked_of(self, p: Path, t: int) -> tuple[np.ndarray, np.ndarray]:
        """(windows, atoms) a vehicle of type ``t`` may not occupy because of path ``p`` (before its
        arrival; the goal hold is separate)."""
        if t not in p.blocked:
            ta = self.agent_of_path(p).type_index
            c = self.rm.conflicts[(ta, t)]
            lens = c.indptr[p.occ_a + 1] - c.indptr[p.occ_a]
            atoms = self.rm.blocked_by(ta, t, p.occ_a)
            wins = np.repeat(p.occ_w, lens)
            p.blocked[t] = (wins, atoms)
        return p.blocked[t]

    # -- low level -------------------------------------------------------------------------------
    def plan(self, ag: Agent, higher: list[Path], horizon: int, parked: tuple = ()) -> Path | None:
        """Space-time A* for ``ag`` against ``higher`` (see module); None when no path is found
        within ``horizon`` windows or ``max_expansions``."""
        blocked_np, perm = self.reservation(ag, higher, horizon, parked)
        blocked = bytearray(blocked_np.tobytes())
        n_atoms = self.n_atoms
        h = self.heuristic(ag)
        nv = self.nv
        s_node, g_node = self.start_node(ag), self.goal_node(ag)
        g_atom = self.rm.endpoint_atom(ag.goal)
        if perm[g_atom] < INF_WINDOW:
            return None  # a higher vehicle holds a goal in conflict with ours
        col = blocked_np.reshape(horizon, n_atoms)[:, g_atom]
        nz = np.flatnonzero(col)
        goal_free_from = int(nz[-1]) + 1 if nz.size else 0
        goal_targets = {v: None for v, _ in self.goal_targets(ag)}
        goal_access = {v: k for v, k in self.access_of.get(ag.goal, [])}
        goal_pos = self.rm.endpoints_m[ag.goal]

        def h_of(node: int) -> float:
            if node < nv:
                return h[node]
            if node == g_node:
                return 0.0
            best = math.inf
            e = node - nv
            for v, _k in self.access_of.get(e, []):
                d = float(np.linalg.norm(self.rm.endpoints_m[e] - self.rm.position(v)))
                best = min(best, self.profiles.run(ag.limits, d)[0] / self.window_s + h[v])
            return best

        def free(k: int, atom: int) -> bool:
            return k < horizon and not blocked[k * n_atoms + atom] and k < perm[atom]

        goal_idx = self.idx[g_node] if g_node < nv else None
        target_idx = [self.idx[v] for v in goal_targets] if goal_idx is None else [goal_idx]
        nodes: list[tuple[int, int, int, Move | None]] = []  # node, k, parent, move
        heap: list = []
        seen: set[int] = set()
        nodes.append((s_node, 0, -1, None))
        heapq.heappush(heap, (self.weight * h_of(s_node), 0, 0))
        expansions = 0
        found = -1
        while heap:
            _f, _ng, i = heapq.heappop(heap)
            node, k, _par, _mv = nodes[i]
            key = node * horizon + k
            if key in seen:
                continue
            seen.add(key)
            if node == g_node and k >= goal_free_from:
                found = i
                break
            expansions += 1
            if expansions > self.max_expansions:
                break
            rest = self.rest_atom(ag, node)

            def push(nb: int, k2: int, mv: Move, parent: int = i) -> None:
                if k2 >= horizon or nb * horizon + k2 in seen:
                    return
                nodes.append((nb, k2, parent, mv))
                heapq.heappush(heap, (k2 + self.weight * h_of(nb), -k2, len(nodes) - 1))

            # wait
            if free(k, rest):
                push(node, k + 1, Move(k, 1, node, node, 0.0))
            if node >= nv:  # an endpoint: access runs to the lattice (or into the goal)
                e = node - nv
                for v, acc in self.access_of.get(e, []):
                    d = float(np.linalg.norm(self.rm.endpoints_m[e] - self.rm.position(v)))
                    dur, sw = self.profiles.run(ag.limits, d)
                    atom = self.rm.access_atom(acc)
                    if all(free(k + j, atom) for j in range(len(sw))):
                        push(v, k + len(sw), Move(k, len(sw), node, v, dur))
                continue
            # lattice vertex: into the goal over an access edge
            if node in goal_access:
                d = float(np.linalg.norm(goal_pos - self.rm.position(node)))
                dur, sw = self.profiles.run(ag.limits, d)
                atom = self.rm.access_atom(goal_access[node])
                if all(free(k + j, atom) for j in range(len(sw))):
                    push(g_node, k + len(sw), Move(k, len(sw), node, g_node, dur))
            # straight runs along every edge kind, both ways
            here = self.idx[node]
            for kind, step, stride, _ell, plus_runs, minus_runs in self.kinds:
                base_kind = kind * nv
                for sgn, runs in ((1, plus_runs), (-1, minus_runs)):
                    m_max = runs[node]
                    if m_max == 0:
                        continue
                    first_edge = node if sgn > 0 else node - stride
                    if not free(k, base_kind + first_edge):
                        continue
                    lengths = {1, 2, 3, m_max}
                    for t_idx in target_idx:
                        for a in range(3):
                            if step[a]:
                                m = (int(t_idx[a]) - int(here[a])) * sgn * int(step[a])
                                if 0 < m <= m_max:
                                    lengths.add(m)
                    for m in sorted(x for x in lengths if x <= m_max):
                        dur, offsets = self.run_offsets(ag.limits, kind, sgn, m)
                        ok = True
                        for j, offs in enumerate(offsets):
                            kj = k + j
                            if kj >= horizon:
                                ok = False
                                break
                            row = kj * n_atoms + node
                            for off in offs:
                                if blocked[row + off] or kj >= perm[node + off]:
                                    ok = False
                                    break
                            if not ok:
                                break
                        if ok:
                            nb = node + sgn * m * stride
                            push(nb, k + len(offsets), Move(k, len(offsets), node, nb, dur))
        if found < 0:
            return None
        moves: list[Move] = []
        i = found
        while i > 0:
            node, k, par, mv = nodes[i]
            assert mv is not None
            moves.append(mv)
            i = par
        moves.reverse()
        path = self.make_path(ag, moves, nodes[found][1])
        path.expansions = expansions
        return path

    def make_path(self, ag: Agent, moves: list[Move], arrival: int) -> Path:
        """Occupancy arrays of a move list."""
        ws: list[int] = []
        ats: list[int] = []
        nv = self.nv
        for mv in moves:
            if mv.a == mv.b:
                ws.append(mv.k0)
                ats.append(self.rest_atom(ag, mv.a))
                continue
            if mv.a >= nv or mv.b >= nv:  # access edge
                e = mv.a - nv if mv.a >= nv else mv.b - nv
                v = mv.b if mv.a >= nv else mv.a
                acc = next(k for vv, k in self.access_of[e] if vv == v)
                for j in range(mv.n):
                    ws.append(mv.k0 + j)
                    ats.append(self.rm.access_atom(acc))
                continue
            diff = self.idx[mv.b] - self.idx[mv.a]
            m = int(np.abs(diff).max())
            unit = diff // m
            kd = next(kd for kd in self.kinds if np.array_equal(unit, kd[1]) or np.array_equal(unit, -kd[1]))
            sgn = 1 if np.array_equal(unit, kd[1]) else -1
            _dur, offsets = self.run_offsets(ag.limits, kd[0], sgn, m)
            for j, offs in enumerate(offsets):
                for off in offs:
                    ws.append(mv.k0 + j)
                    ats.append(mv.a + off)
        p = Path(
            moves,
            arrival,
            np.array(ws, dtype=np.int64),
            np.array(ats, dtype=np.int64),
            self.rm.endpoint_atom(ag.goal),
        )
        p._agent = ag  # type: ignore[attr-defined]
        return p

    # -- conflicts between paths -----------------------------------------------------------------
    def first_conflict(self, pa: Path, pb: Path) -> int | None:
        """Earliest window in which paths ``pa`` and ``pb`` conflict, or None."""
        ta, tb = self.agent_of_path(pa).type_index, self.agent_of_path(pb).type_index
        best = None
        w, a = self.blocked_of(pa, tb)
        if w.size and pb.occ_w.size:
            kb = pb.occ_w * self.n_atoms + pb.occ_a
            ka = w * self.n_atoms + a
            hit = np.isin(kb, ka)
            if hit.any():
                best = int(pb.occ_w[hit].min())
        # goal holds against the other's occupancy
        for p, q, tp, tq in ((pa, pb, ta, tb), (pb, pa, tb, ta)):
            g = self.rm.blocked_by(tp, tq, np.array([p.goal_atom]))
            late = q.occ_w >= p.arrival
            if late.any():
                hit = np.isin(q.occ_a[late], g)
                if hit.any():
                    k = int(q.occ_w[late][hit].min())
                    best = k if best is None else min(best, k)
            if q.goal_atom in set(g.tolist()):
                k = max(p.arrival, q.arrival)
                best = k if best is None else min(best, k)
        return best


def _shifted(arr: np.ndarray, step: np.ndarray) -> np.ndarray:
    """out[u] = arr[u - step] where that index exists, else 0 / False."""
    out = np.zeros_like(arr)
    src = tuple(slice(max(0, -int(s)), arr.shape[a] - max(0, int(s))) for a, s in enumerate(step))
    dst = tuple(slice(max(0, int(s)), arr.shape[a] - max(0, -int(s))) for a, s in enumerate(step))
    out[dst] = arr[src]
    return out
