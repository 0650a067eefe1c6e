"""The multi-agent layer of the swarm search on the shared roadmap: prioritised planning (PP, one
fixed order, longest flight first) and priority-based search (PBS, Ma et al. AAAI 2019), both calling
the single-vehicle space-time A* of :class:`proxplan.planner.swarm.search.Search`.

* **PBS**: depth-first search over partial priority orders; at a node, the earliest conflict (a, b)
  branches into "a before b" and "b before a"; the lower vehicle and every vehicle below it that now
  conflicts with a higher one are re-planned against all higher ones. A cap on high-level nodes (a
  count) ends it.
* **PP**: every vehicle against all before it, the ones not planned yet parked at their starts; a
  failed vehicle moves to the front (a bounded number of restarts). The baseline PBS improves on.
"""

from __future__ import annotations

from dataclasses import dataclass

from proxplan.planner.swarm.runs import INF_WINDOW, Path
from proxplan.planner.swarm.search import Search


def order_longest_first(search: Search) -> list[int]:
    """Agents by decreasing roadmap lower bound (ties in input order)."""
    lb = [search.lower_bound_windows(a) for a in search.agents]
    return sorted(range(len(search.agents)), key=lambda i: (-lb[i], i))


@dataclass
class SearchResult:
    paths: list[Path] | None
    method: str
    high_level_nodes: int = 0
    low_level_calls: int = 0
    expansions: int = 0
    message: str = ""


def prioritized(
    search: Search, horizon: int, *, park: bool = True, restarts: int = 20, shortest_first: bool = False
) -> SearchResult:
    """PP: every agent against all before it, in ``order_longest_first`` (or reversed), the ones
    not planned yet parked at their starts (``park``); a failed agent moves to the front and
    planning restarts, at most ``restarts`` times (deterministic)."""
    order = order_longest_first(search)
    if shortest_first:
        order = order[::-1]
    res = SearchResult(None, "pp")
    tried = {tuple(order)}
    for _attempt in range(restarts + 1):
        paths: list[Path | None] = [None] * len(search.agents)
        done: list[Path] = []
        failed = None
        for pos, i in enumerate(order):
            parked = tuple(search.agents[j] for j in order[pos + 1 :]) if park else ()
            p = search.plan(search.agents[i], done, horizon, parked)
            res.low_level_calls += 1
            if p is None:
                failed = pos
                break
            res.expansions += p.expansions
            paths[i] = p
            done.append(p)
        if failed is None:
            res.paths = [p for p in paths if p is not None]
            return res
        res.high_level_nodes += 1
        bad = order[failed]
        res.message = f"vehicle {search.agents[bad].name!r}: no roadmap path against the ones before it"
        new = [bad] + [x for x in order if x != bad]
        if tuple(new) in tried:
            break
        tried.add(tuple(new))
        order = new
    return res


def pbs(search: Search, horizon: int, *, max_nodes: int = 300) -> SearchResult:
    """Priority-based search (see module); depth-first, cheaper child first."""
    n = len(search.agents)
    res = SearchResult(None, "pbs")
    root_paths: list[Path] = []
    order = order_longest_first(search)
    # root: a prioritized pass gives the root paths (a valid PBS root: any paths will do); its
    # priorities are not kept, conflicts are resolved by branching
    leave = [search.leave_windows(a) for a in search.agents]
    for i in range(n):
        parked = tuple((search.agents[y], _departure(root_paths[y]) if y < i else leave[y]) for y in range(n) if y != i)
        p = search.plan(search.agents[i], [], horizon, parked)
        res.low_level_calls += 1
        if p is None:
            res.message = f"vehicle {search.agents[i].name!r}: no roadmap path even alone"
            return res
        res.expansions += p.expansions
        root_paths.append(p)
    del order

    def conflicts_of(paths: list[Path], who: list[int], table: dict) -> None:
        for i in who:
            for j in range(n):
                if j == i:
                    continue
                key = (min(i, j), max(i, j))
                table.pop(key, None)
            for j in range(n):
                if j == i:
                    continue
                w = search.first_conflict(paths[i], paths[j])
                if w is not None:
                    table[(min(i, j), max(i, j))] = w

    table: dict = {}
    conflicts_of(root_paths, list(range(n)), table)
    stack: list[tuple[list[Path], frozenset, dict]] = [
        (root_paths, frozenset(), table)
    ]  # paths, priority edges (hi, lo), conflicts
    while stack:
        paths, prio, table = stack.pop()
        res.high_level_nodes += 1
        if not table:
            res.paths = paths
            return res
        if res.high_level_nodes > max_nodes:
            res.message = f"priority-based search: no conflict-free plan within {max_nodes} nodes"
            return res
        (i, j), _w = min(table.items(), key=lambda kv: (kv[1], kv[0]))
        children = []
        for hi, lo in ((i, j), (j, i)):
            if _reaches(prio, lo, hi):
                continue  # lo is already above hi
            new_prio = prio | {(hi, lo)}
            new_paths = list(paths)
            new_table = dict(table)
            ok = True
            for x in _topological_below(new_prio, lo, n):
                above = _ancestors(new_prio, x)
                if x != lo and not any((min(x, y), max(x, y)) in new_table for y in above):
                    continue
                parked = tuple(
                    (search.agents[y], _departure(new_paths[y]))
                    for y in range(n)
                    if y != x and y not in above and _departure(new_paths[y]) > 0
                )
                p = search.plan(search.agents[x], [new_paths[y] for y in sorted(above)], horizon, parked)
                res.low_level_calls += 1
                if p is None:
                    ok = False
                    break
                res.expansions += p.expansions
                new_paths[x] = p
                conflicts_of(new_paths, [x], new_table)
            if ok:
                cost = sum(p.arrival for p in new_paths)
                children.append((cost, len(new_table), new_paths, new_prio, new_table))
        children.sort(key=lambda c: (c[0], c[1]), reverse=True)
        for c in children:
            stack.append((c[2], c[3], c[4]))
    res.message = res.message or "priority-based search: every priority order failed"
    return res


def _departure(p: Path) -> int:
    """Window at which the vehicle's first run ends, i.e. it has left its start (INF_WINDOW: never
    leaves)."""
    for mv in p.moves:
        if mv.a != mv.b:
            return mv.k0 + mv.n
    return INF_WINDOW


def _reaches(prio: frozenset, a: int, b: int) -> bool:
    """Whether a is above b (a path of priority edges a -> ... -> b)."""
    out: dict[int, list[int]] = {}
    for hi, lo in prio:
        out.setdefault(hi, []).append(lo)
    stack, seen = [a], {a}
    while stack:
        x = stack.pop()
        if x == b:
            return True
        for y in out.get(x, []):
            if y not in seen:
                seen.add(y)
                stack.append(y)
    return False


def _ancestors(prio: frozenset, x: int) -> set[int]:
    into: dict[int, list[int]] = {}
    for hi, lo in prio:
        into.setdefault(lo, []).append(hi)
    stack, seen = [x], set()
    while stack:
        y = stack.pop()
        for z in into.get(y, []):
            if z not in seen:
                seen.add(z)
                stack.append(z)
    return seen


def _topological_below(prio: frozenset, lo: int, n: int) -> list[int]:
    """``lo`` and every agent below it, each after all of its ancestors among them."""
    out: dict[int, list[int]] = {}
    for hi, l2 in prio:
        out.setdefault(hi, []).append(l2)
    below, stack = {lo}, [lo]
    while stack:
        x = stack.pop()
        for y in out.get(x, []):
            if y not in below:
                below.add(y)
                stack.append(y)
    order: list[int] = []
    indeg = {x: 0 for x in below}
    for hi, l2 in prio:
        if hi in below and l2 in below:
            indeg[l2] += 1
    ready = sorted(x for x in below if indeg[x] == 0)
    while ready:
        x = ready.pop(0)
        order.append(x)
        for y in sorted(out.get(x, [])):
            if y in indeg:
                indeg[y] -= 1
                if indeg[y] == 0:
                    ready.append(y)
        ready.sort()
    return order
