"""The CasADi trajectory-optimisation problem (``Opti`` + IPOPT) of the optimised planner.

All moving vehicles are optimised jointly on one uniform time grid of ``n_intervals`` intervals over
a free common duration T (s), the makespan. Each moving vehicle is a triple integrator in the world
frame (z up) with state x = (p_m, v_mps, a_mps2) at the grid nodes and a piecewise-constant jerk
input j_mps3 per interval; multiple shooting with the exact discretisation of the integrator

    p+ = p + h v + h^2/2 a + h^3/6 j,   v+ = v + h a + h^2/2 j,   a+ = a + h j,   h = T / n

so the node states describe the continuous trajectory exactly. Hovering vehicles are constants.

Path constraints are imposed at *check points*: every node and every interval midpoint (the exact
midpoint position p + h/2 v + h^2/8 a + h^3/48 j), so nothing slips through between nodes:
start at rest, goal (absolute, or the dock partner's final position plus the dock offset) at rest;
speed / acceleration / jerk norms (the verifier's convention); workspace box shrunk by the body
radius; axis-aligned box obstacles by side selection from the warm start (the face the warm-start
point is furthest outside of); pairwise separation; the model's invalid zone (0 < dz <= 3 L of a
source with overlapping footprints, S0 II-A) enclosed by a smooth super-ellipsoid; a dock pair
on its final approach stays on the dock axis instead; and **authority usage <= authority_fraction**
for every vehicle: the disturbance wrench (F_z, tau_x, tau_y) on a target from each other vehicle
comes from the differentiable wrench table of ``proxplan.costmaps.map_store`` (the same numbers as
``proxplan.physics.disturbance``), is summed over sources and mapped through the inverse mixer of (S0-14)
(``proxplan.physics.authority.mixer_matrix``) to per-motor thrust changes, each bounded by
``fraction x headroom`` in its direction (DESIGN.md section 3) -- exactly ``usage <= fraction``
without a non-smooth max.

Objective: T + w_smooth * integral |j / j_max|^2 dt + w_exposure * integral of the summed squared
normalised motor changes (disturbance exposure).

The table's ``casadi.Function.bspline`` has no SX form. By default the table is therefore
linearised at the current offsets (value and Jacobian from its own CasADi function), the NLP is
SX-expanded and solved, and the linearisation is repeated a few times (sequential linearisation);
the exact table (MX, ``expand=False``) remains available. The final plan is always checked against
the model directly by :mod:`proxplan.verify.checks`. Problem data and results: :mod:`proxplan.planner.optimizer.ocp_problem`; the
problem is assembled in :mod:`proxplan.planner.optimizer.ocp_builder` (variables, dynamics, pairs)
and :mod:`proxplan.planner.optimizer.ocp_authority`, and solved in
:mod:`proxplan.planner.optimizer.ocp_solve`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from proxplan.planner.optimizer.ocp_authority import add_authority
from proxplan.planner.optimizer.ocp_builder import OcpBuilder
from proxplan.planner.optimizer.ocp_problem import OcpProblem, OcpSolution
from proxplan.planner.optimizer.ocp_solve import solve
from proxplan.planner.optimizer.ocp_warm import repair_warm_start


def build_and_solve(
    problem: OcpProblem,
    *,
    progress: Callable[[str], None] | None = None,
    accept: Callable[[OcpSolution], bool] | None = None,
) -> OcpSolution:
    """Build the Opti problem, warm-start it and solve it with IPOPT (print_level 0).

    With the linearised table, ``accept(solution)`` is asked after each converged round; True stops
    the re-linearisation early (e.g. when the verifier already passes)."""
    t0 = time.perf_counter()
    problem, _ = repair_warm_start(problem)
    b = OcpBuilder(problem)
    b.add_vehicles()
    b.add_pairs()
    add_authority(b)
    build_time = time.perf_counter() - t0
    sol = solve(b, progress, accept)
    return OcpSolution(**{**sol.__dict__, "build_time_s": build_time})


def sample_solution(
    solution: OcpSolution, times_s: np.ndarray, *, time_scale: float = 1.0
) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Evaluate the piecewise-constant-jerk trajectories exactly at ``times_s`` (M,), s.

    ``time_scale`` >= 1 slows the whole solution uniformly (duration x s; v / s, a / s^2).
    Returns {name: (position_m (M, 3), velocity_mps (M, 3), acceleration_mps2 (M, 3))}.
    """
    nodes = solution.times_s()  # (n+1,) s
    n = nodes.size - 1
    tau = np.clip(np.asarray(times_s, float) / time_scale, 0.0, solution.duration_s)
    k = np.clip(np.searchsorted(nodes, tau, side="right") - 1, 0, n - 1)
    dt = (tau - nodes[k])[:, None]
    out = {}
    for name in solution.position_m:
        p0, v0 = solution.position_m[name][k], solution.velocity_mps[name][k]
        a0, j = solution.acceleration_mps2[name][k], solution.jerk_mps3[name][k]
        p = p0 + v0 * dt + a0 * dt**2 / 2 + j * dt**3 / 6
        v = (v0 + a0 * dt + j * dt**2 / 2) / time_scale
        a = (a0 + j * dt) / time_scale**2
        out[name] = (p, v, a)
    return out
