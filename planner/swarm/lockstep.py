"""From a coordination plan to trajectories: every step flown together (lock-step).

Step k of the plan (configurations Q_{k-1} -> Q_k, :mod:`proxplan.planner.swarm.lacam`) starts when
step k - 1 has ended; its moving vehicles fly their straight moves along one common rest-to-rest
profile (the step's longest move at the moving vehicles' common limits,
:func:`proxplan.planner.timing.profile.rest_to_rest`), the others hold. So in every step the relative
position of any two vehicles runs on the straight segment the synchronous test checked
(:mod:`proxplan.planner.swarm.sync`): a conflict-free plan gives conflict-free trajectories, at
every speed and type mix. This is the guaranteed conversion; :mod:`proxplan.planner.swarm.retime`
then shortens it in continuous time.
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.lattice import Lattice
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.profile import LineMove, rest_to_rest


def lockstep_tracks(lattice: Lattice, configurations: list[tuple[int, ...]]) -> list[GridTrack]:
    """One :class:`GridTrack` per agent flying ``configurations`` in lock-step (see module)."""
    problem = lattice.problem
    pos = lattice.pos_m
    A = problem.n_agents
    moves: list[list[tuple[int, LineMove]]] = [[] for _ in range(A)]
    t = 0
    for k in range(1, len(configurations)):
        u = np.asarray(configurations[k - 1])
        v = np.asarray(configurations[k])
        movers = np.flatnonzero(u != v)
        if movers.size == 0:
            continue
        lengths = np.linalg.norm(pos[v[movers]] - pos[u[movers]], axis=1)
        profile = rest_to_rest(float(lengths.max()), problem.common_limits(movers.tolist()), GRID_DT_S)
        for a in movers.tolist():
            moves[a].append((t, LineMove(pos[u[a]], pos[v[a]], profile)))
        t += profile.steps
    return [GridTrack(a, int(problem.type_index[a]), pos[configurations[0][a]], moves[a]) for a in range(A)]
