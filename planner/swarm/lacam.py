"""Joint coordination: LaCAM (Okumura, AAAI 2023) with PIBT (Okumura et al., AIJ 2022) as its
configuration generator, for large agents with synchronous conflicts.

A *configuration* is one vertex per agent; a *step* moves every agent at once from one
configuration to the next along a straight move of the lattice (:meth:`Lattice.moves`) or keeps it
in place. A step is valid when every pair of agents passes :class:`~proxplan.planner.swarm.sync.SyncTable`
(the exact synchronous test). LaCAM searches configurations depth-first; each search node expands
lazily through a tree of low-level constraints ("agent i goes to v"), and PIBT proposes the next
configuration under those constraints. The search is complete on finite graphs: it returns a plan
or proves that none exists within the graph, unless its count budget (``max_nodes``) or the caller's
deadline stops it first; then it says so (:class:`~proxplan.planner.errors.PlanNotFound`), it never reports "infeasible".

PIBT with large agents: an agent tries its candidate vertices in order of the distance to its goal
(ties broken by a seeded random order; staying put is one of them); a candidate must be compatible
with every agent already decided in this step; agents not decided yet whose staying put would
conflict with it are asked to move first (priority inheritance, recursively). A candidate that fails
*undoes every decision made under it* (the agents it pushed, theirs, ...) before the next is tried.
So after an agent's call returns, every agent decided is compatible with every other decided agent
and with the staying put of every agent not decided yet (each decision pushed those it would hit,
and a failed branch leaves no decision behind); an agent called from the top of the step can then
always stay (no agent on the stack; the current configuration is valid at rest), and a proposal
fails only where the constraint holds an agent to a vertex it cannot take. Undoing can re-try the
same agents many times (exponentially in a long queue: corridor-128), so it runs within a count of
candidate tries: as many as PIBT without undo makes at most (each agent decided once, each of its
candidates tried once). Once spent, PIBT goes on without undo (a failed candidate's decisions stay,
a pushed agent that cannot move stays) and the step is then *settled*: the movers of every pair in
conflict stay put until no pair is (all staying is valid), and the proposal fails only if that
stops an agent the constraint moves. Without undo from the start (point-agent PIBT, where an agent
left in place never blocks its pusher's other vertices) a proposal was thrown away at the first
conflict a failed branch left behind; the chance that none is left falls with every vehicle that
interacts, and on grid-128 fixed LaCAM's 4000 proposals added one configuration (issue 37, round
12A in docs/planner.md).

The table is asked only about pairs that may come within reach: an agent's neighbours are those
within the widest keep-out plus two longest moves of it (any pair of moves), and before a pair is
asked one vectorised test (:func:`~proxplan.planner.swarm.sync.maybe_near`, conservative: it rules
out only pairs that :func:`~proxplan.planner.swarm.sync.far_apart` clears) takes every candidate of
an agent against every decided neighbour at once, each move against the staying neighbours, and the
settle and the final check against every end each agent can take. The same answers, so the same
search (tested); the table was asked about 40 times per candidate, nearly all pairs far apart
(issue 37, round 18B).
"""

from __future__ import annotations

import random
import time
from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.lattice import Lattice
from proxplan.planner.swarm.sync import SyncTable, maybe_near


@dataclass(frozen=True)
class LacamResult:
    configurations: list[tuple[int, ...]]  # Q_0 (starts) .. Q_K (goals), vertex per agent
    nodes: int  # configurations generated
    tests: int  # exact synchronous tests computed (cache misses)
    proposals: int = 0  # PIBT proposals made (the budget's other count)


class _Constraint:
    __slots__ = ("parent", "who", "where", "depth")

    def __init__(self, parent=None, who: int = -1, where: int = -1):
        self.parent, self.who, self.where = parent, who, where
        self.depth = 0 if parent is None else parent.depth + 1

    def fixed(self) -> dict[int, int]:
        out = {}
        c = self
        while c is not None and c.who >= 0:
            out[c.who] = c.where
            c = c.parent
        return out


class _Node:
    __slots__ = ("config", "parent", "tree", "order", "priority")

    def __init__(self, config, parent, order, priority):
        self.config, self.parent, self.order, self.priority = config, parent, order, priority
        self.tree = deque([_Constraint()])


class Lacam:
    """LaCAM on ``lattice`` with the conflict table ``sync`` (see module)."""

    def __init__(self, lattice: Lattice, sync: SyncTable, *, seed: int = 0):
        self.lat = lattice
        self.sync = sync
        p = lattice.problem
        self.A = p.n_agents
        self.pinned = [bool(x) for x in p.pinned]
        self.r_xy = p.reach_xy_m + 2.0 * lattice.longest_move_m() + 1e-6
        span = float(lattice.levels_m[-1] - lattice.levels_m[0]) if len(lattice.levels_m) > 1 else 0.0
        self.r_z = p.reach_z_m + 2.0 * span + 1e-6
        self.rng = random.Random(seed)
        self.goal = tuple(int(v) for v in lattice.goal_v)
        assert lattice.dist_to_goal is not None
        self.dist = lattice.dist_to_goal
        # horizontal vertex positions from the table's whole millimetres, m; agent types; per type pair
        # the horizontal reach beyond which a relative segment cannot conflict (moving or at rest), m
        self.xy_m = np.asarray(sync.pos, dtype=float)[:, :2] * 1e-3 if sync.pos else np.zeros((0, 2))
        self.types = np.asarray(sync.types, dtype=np.intp)
        self.reach_pair_m = sync.reach_any_m

    def _near(self, config) -> tuple[list[list[int]], np.ndarray]:
        """Per agent, the agents whose moves from ``config`` may interact with its own (within the
        reach of the widest keep-out and two longest moves), and those pairs (P, 2), a < b, in the
        order the lists were built from."""
        p = self.lat.pos_m[list(config)]
        pairs = cKDTree(p[:, :2]).query_pairs(self.r_xy, output_type="ndarray")
        nb: list[list[int]] = [[] for _ in range(self.A)]
        if len(pairs):
            pairs = pairs[np.abs(p[pairs[:, 0], 2] - p[pairs[:, 1], 2]) < self.r_z]
            for a, b in pairs.tolist():
                nb[a].append(b)
                nb[b].append(a)
        return nb, pairs

    def _near_pairs(self, Q, pairs: np.ndarray, ends_a: tuple, ends_b: tuple) -> list[list[int]]:
        """Per agent, its partners among ``pairs`` (in the order :meth:`_near` lists them) that may
        conflict (:func:`~proxplan.planner.swarm.sync.maybe_near`) when the first of a pair moves
        from Q to any of ``ends_a`` (configurations) and the second to any of ``ends_b``."""
        out: list[list[int]] = [[] for _ in range(self.A)]
        if not len(pairs):
            return out
        xy = self.xy_m
        a, b = pairs[:, 0], pairs[:, 1]
        qa, qb = xy[np.asarray(Q)[a]], xy[np.asarray(Q)[b]]
        reach = self.reach_pair_m[self.types[a], self.types[b]]
        keep = np.zeros(len(pairs), dtype=bool)
        for ea in ends_a:
            xa = xy[np.asarray(ea)[a]]
            for eb in ends_b:
                keep |= maybe_near(qb - qa, xy[np.asarray(eb)[b]] - xa, reach)
        for i, j in pairs[keep].tolist():
            out[i].append(j)
            out[j].append(i)
        return out

    def _near_decided(self, Q, i: int, cands: list[int], decided: list[int], to: list[int]) -> list[list[bool]]:
        """Per candidate v of agent i (moving Q[i] -> v), per decided neighbour j (moving Q[j] ->
        to[j]): may the pair conflict (:func:`~proxplan.planner.swarm.sync.maybe_near`)? One
        vectorised test of every candidate against every decided neighbour."""
        xy = self.xy_m
        dj = np.array(decided, dtype=np.intp)
        d0 = xy[[Q[j] for j in decided]] - xy[Q[i]]  # (N, 2)
        d1 = xy[[to[j] for j in decided]][None, :, :] - xy[cands][:, None, :]  # (C, N, 2)
        reach = self.reach_pair_m[self.types[i], self.types[dj]]
        return maybe_near(d0[None, :, :], d1, reach[None, :]).tolist()

    def _near_staying(self, Q, i: int, v: int, among: list[int]) -> list[int]:
        """The agents of ``among`` whose staying put agent i's move Q[i] -> v may reach (the rest
        cannot conflict with it staying), in the order of ``among``."""
        if not among:
            return among
        xy = self.xy_m
        k = np.array(among, dtype=np.intp)
        here = xy[[Q[j] for j in among]]
        near = maybe_near(here - xy[Q[i]], here - xy[v], self.reach_pair_m[self.types[i], self.types[k]])
        return [j for j, m in zip(among, near.tolist()) if m]

    def _candidates(self, i: int, u: int) -> list[int]:
        if self.pinned[i]:
            return [u]
        cands = self.lat.moves(i, u) + [u]
        self.rng.shuffle(cands)
        di = self.dist[i]
        cands.sort(key=lambda v: float(di[v]))
        return cands

    def _generate(self, node: _Node, constraint: _Constraint) -> tuple[int, ...] | None:
        """PIBT proposal of the next configuration under ``constraint``, or None (see module)."""
        Q = node.config
        to = [-1] * self.A
        fixed = constraint.fixed()
        nb, pairs = self._near(Q)
        conflict = self.sync.conflict
        trail: list[int] = []  # agents decided, in order (a failed branch undoes its own)
        # candidate vertices tried with undo: as many as PIBT without undo tries at most (each agent
        # decided once, each of its candidates tried once); once spent, PIBT goes on without undo
        tries = [sum(1 if self.pinned[i] else len(self.lat.moves(i, Q[i])) + 1 for i in range(self.A))]

        def compatible(i: int, v: int, among: list[int]) -> bool:
            ui = Q[i]
            for j in among:
                vj = to[j]
                if vj >= 0 and conflict(i, ui, v, j, Q[j], vj):
                    return False
            return True

        def undo(mark: int) -> None:
            while len(trail) > mark:
                to[trail.pop()] = -1

        def pibt(i: int) -> bool:
            ui = Q[i]
            cands = [fixed[i]] if i in fixed else self._candidates(i, ui)
            # the decided neighbours each candidate may reach (the rest cannot conflict with it), taken
            # when the decisions are as at entry and again whenever a failed candidate's stay (no undo)
            decided = [j for j in nb[i] if to[j] >= 0]
            near = self._near_decided(Q, i, cands, decided, to) if decided else None
            for c, v in enumerate(cands):
                tries[0] -= 1
                if near is not None and not compatible(i, v, [j for j, m in zip(decided, near[c]) if m]):
                    continue
                mark = len(trail)
                to[i] = v
                trail.append(i)
                good = True
                for k in self._near_staying(Q, i, v, nb[i]):
                    if to[k] >= 0 or not conflict(i, ui, v, k, Q[k], Q[k]):
                        continue
                    if (k in fixed and fixed[k] == Q[k]) or self.pinned[k] or not pibt(k):
                        good = False
                        break
                if good:
                    return True
                if tries[0] > 0:
                    undo(mark)
                else:
                    to[i] = -1  # the decisions under v stay: the next candidates see them
                    decided = [j for j in nb[i] if to[j] >= 0]
                    near = self._near_decided(Q, i, cands, decided, to) if decided else None
            if tries[0] <= 0 and to[i] < 0:
                to[i] = ui
                trail.append(i)
            return False

        for i in list(fixed) + list(node.order):
            if to[i] < 0 and not pibt(i) and tries[0] > 0:
                return None  # only an agent held by the constraint can fail here (see module)
        if tries[0] <= 0:  # settle: the movers of a pair in conflict stay put until none is left
            # every agent ends at its proposal or stays: the pairs that may conflict in any of those
            nbs = self._near_pairs(Q, pairs, (to, Q), (to, Q))
            todo = set(range(self.A))
            while todo:
                moved: set[int] = set()
                for i in todo:
                    for j in nbs[i]:
                        if conflict(i, Q[i], to[i], j, Q[j], to[j]):
                            for a in (i, j):
                                if to[a] != Q[a]:
                                    to[a] = Q[a]
                                    moved.add(a)
                todo = set(moved)
                for a in moved:
                    todo.update(nb[a])
            if any(to[i] != v for i, v in fixed.items()):
                return None
        nbs = self._near_pairs(Q, pairs, (to,), (to,))
        for i in range(self.A):  # the whole step once more, exactly
            for j in nbs[i]:
                if j > i and conflict(i, Q[i], to[i], j, Q[j], to[j]):
                    return None
        return tuple(to)

    def _order(self, priority: list[float]) -> list[int]:
        return sorted(range(self.A), key=lambda i: -priority[i])

    def solve(
        self, *, max_nodes: int, max_proposals: int | None = None, deadline: float | None = None, progress=None
    ) -> LacamResult:
        """A plan from the starts to the goals; :class:`~proxplan.planner.errors.PlanNotFound` when the budget ends first or
        the lattice holds none (that proves nothing about continuous space). The budget counts new
        configurations (``max_nodes``) and PIBT proposals (``max_proposals``, None: no cap): a
        search whose proposals keep failing or revisiting configurations adds no configuration
        and would otherwise run unbounded."""
        start = tuple(int(v) for v in self.lat.start_v)
        priority = [float(self.dist[i][start[i]]) * 1e-3 for i in range(self.A)]
        root = _Node(start, None, self._order(priority), priority)
        explored = {start: root}
        stack = [root]
        n = 1
        generated = 0  # PIBT proposals (most of the work; many fail or revisit a configuration)
        while stack:
            node = stack[-1]
            if node.config == self.goal:
                out = []
                cur: _Node | None = node
                while cur is not None:
                    out.append(cur.config)
                    cur = cur.parent
                return LacamResult(out[::-1], n, self.sync.computed, generated)
            if not node.tree:
                stack.pop()
                continue
            c = node.tree.popleft()
            if c.depth < self.A:
                i = node.order[c.depth]
                vs = self._candidates(i, node.config[i])
                for v in vs:
                    node.tree.append(_Constraint(c, i, v))
            generated += 1
            if max_proposals is not None and generated > max_proposals:
                raise PlanNotFound(
                    f"no plan found within {max_proposals} configuration proposals", details={"nodes": n}
                )
            if deadline is not None and time.perf_counter() > deadline:
                raise PlanNotFound("no plan found within the time budget", details={"nodes": n})
            nxt = self._generate(node, c)
            if nxt is None:
                continue
            if nxt in explored:
                stack.append(explored[nxt])
                continue
            n += 1
            if n > max_nodes:
                raise PlanNotFound(f"no plan found within {max_nodes} configurations", details={"nodes": n})
            if deadline is not None and time.perf_counter() > deadline:
                raise PlanNotFound("no plan found within the time budget", details={"nodes": n})
            if progress is not None and n % 25 == 0:
                progress(f"coordination: {n} configurations", min(0.5, 0.1 + n / max_nodes))
            pr = [
                node.priority[i] + 1.0 if nxt[i] != self.goal[i] else node.priority[i] - int(node.priority[i])
                for i in range(self.A)
            ]
            child = _Node(nxt, node, self._order(pr), pr)
            explored[nxt] = child
            stack.append(child)
        raise PlanNotFound(
            f"the coordination lattice holds no plan (all {n} configurations searched)", details={"nodes": n}
        )
