"""Solving the assembled Opti problem with IPOPT: sequential linearisation of the wrench table
(value and Jacobian from its own CasADi function, re-set between rounds), the solve loop with an
optional early acceptance, and the :class:`OcpSolution` read back from the solver."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from proxplan.planner.optimizer.ocp_builder import OcpBuilder
from proxplan.planner.optimizer.ocp_problem import OcpSolution

_JACOBIANS: dict[int, tuple[Any, Any]] = {}  # id(fn) -> (fn, its jacobian); fn kept alive with it


def _jacobian(fn):
    """``fn.jacobian()``, built once per wrench function (about 1 s for a B-spline table)."""
    if id(fn) not in _JACOBIANS:
        _JACOBIANS[id(fn)] = (fn, fn.jacobian())
    return _JACOBIANS[id(fn)][1]


def linearize(b: OcpBuilder, evaluate) -> float:
    """Set the table's linear models about the offsets ``evaluate(expr)`` gives; returns the
    largest change of the offsets from the previous linearisation point, m."""
    ca = b.ca
    moved = 0.0
    for g in b.linear_groups:
        o = np.asarray(evaluate(g["offsets"]), float).reshape(3, -1)
        m = o.shape[1]
        fn = g["fn"]
        if "jac_map" not in g:
            g["val_map"] = fn.map(m)
            g["jac_map"] = _jacobian(fn).map(m)
        w = np.asarray(g["val_map"](o)).reshape(3, m)
        jac_flat = np.asarray(g["jac_map"](o, ca.DM.zeros(3, m))).reshape(3, 3 * m, order="F")
        # jacobian().map gives (3, 3 m): block k is d wrench / d offset at column k
        jac = jac_flat.reshape(3, m, 3).transpose(0, 2, 1)  # (out i, in j, point k)
        if "last" in g:
            moved = max(moved, float(np.abs(o - g["last"]).max()))
        g["last"] = o
        b.opti.set_value(g["o0"], o)
        b.opti.set_value(g["w0"], w)
        b.opti.set_value(g["jac"], jac.reshape(9, m))
    return moved


def solve(b: OcpBuilder, progress, accept=None) -> OcpSolution:
    opti, pb = b.opti, b.pb
    opti.minimize(b.cost)
    opti.solver(
        "ipopt",
        {"expand": pb.expand or pb.linearize, "print_time": False},
        {
            "print_level": 0,
            "sb": "yes",
            "max_iter": pb.max_iterations,
            "max_cpu_time": pb.max_cpu_time_s,
            "max_wall_time": pb.max_wall_time_s or 2.0 * pb.max_cpu_time_s,
            "tol": 1e-6,
            "acceptable_tol": 1e-4,
            "mu_strategy": "adaptive",
            "hessian_approximation": pb.hessian,
            "linear_solver": pb.linear_solver,
        },
    )
    if progress is not None:
        progress(f"optimiser: {opti.nx} variables, {opti.ng} constraints")
    t0 = time.perf_counter()
    iterations = 0
    rounds = pb.max_linearizations if b.linear_groups else 1
    if b.linear_groups:
        linearize(b, lambda e: opti.debug.value(e, opti.initial()))
    best = None
    solves = 0
    for r in range(rounds):
        solves += 1
        try:
            sol = opti.solve()
            value, stats, ok = sol.value, sol.stats(), True
        except RuntimeError:
            value, stats, ok = opti.debug.value, opti.stats(), False
        iterations += int(stats.get("iter_count", 0))
        ok = ok and bool(stats.get("success", False))
        if not ok:
            if best is not None:  # keep the last converged linearisation round
                value, stats, ok = best
            break
        best = (value, stats, ok)
        if not b.linear_groups or r == rounds - 1 or time.perf_counter() - t0 > pb.max_cpu_time_s:
            break
        if accept is not None and accept(collect(b, value, stats, ok, iterations, time.perf_counter() - t0, r + 1)):
            break  # the caller's check (the verifier) already passes: no further linearisation
        moved = linearize(b, value)
        if progress is not None:
            progress(f"optimiser: linearisation {r + 1}: offsets moved {moved:.3f} m, {iterations} iterations")
        if moved < pb.linearization_tol:
            break
        opti.set_initial(sol.value_variables())
        opti.set_initial(opti.lam_g, sol.value(opti.lam_g))
    return collect(b, value, stats, ok, iterations, time.perf_counter() - t0, solves)


def collect(b: OcpBuilder, value, stats, ok: bool, iterations: int, solve_time: float, rounds: int = 1) -> OcpSolution:
    pb, n = b.pb, b.n
    out_p, out_v, out_a, out_j = {}, {}, {}, {}
    for a in pb.agents:
        if a.moving:
            x = np.asarray(value(b.X[a.name])).reshape(9, n + 1)
            out_p[a.name], out_v[a.name], out_a[a.name] = x[0:3].T, x[3:6].T, x[6:9].T
            out_j[a.name] = np.asarray(value(b.U[a.name])).reshape(3, n).T
        else:
            out_p[a.name] = np.tile(np.asarray(a.start_m, float), (n + 1, 1))
            out_v[a.name] = np.zeros((n + 1, 3))
            out_a[a.name] = np.zeros((n + 1, 3))
            out_j[a.name] = np.zeros((n, 3))
    if b.phase_T:
        h_row = np.asarray(value(b.h_row), float).reshape(-1)
    else:
        assert pb.fixed_duration_s is not None
        h_row = np.full(n, pb.fixed_duration_s / n)
    try:  # largest violation of the (linearised) NLP's constraints at the returned point
        g = np.asarray(value(b.opti.g), float).reshape(-1)
        lbg = np.asarray(value(b.opti.lbg), float).reshape(-1)
        ubg = np.asarray(value(b.opti.ubg), float).reshape(-1)
        violation = float(np.max(np.concatenate([[0.0], lbg - g, g - ubg])))
    except (RuntimeError, ValueError):
        violation = float("nan")
    return OcpSolution(
        success=ok,
        status=str(stats.get("return_status", "unknown")),
        duration_s=float(np.sum(h_row)),
        node_times_s=np.concatenate([[0.0], np.cumsum(h_row)]),
        constraint_violation=violation,
        rounds=rounds,
        position_m=out_p,
        velocity_mps=out_v,
        acceleration_mps2=out_a,
        jerk_mps3=out_j,
        iterations=iterations,
        solve_time_s=solve_time,
        build_time_s=0.0,
        objective=float(value(b.cost)),
    )
