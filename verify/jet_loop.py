"""Every vehicle's closed loop along its plan: how far beyond the tube the verifier grants it is
predicted to leave its plan (flying its own reference, and in another's jet), and whether its loop
stays damped where it holds.

Every vehicle flying its plan is off it by e(t), the response of its loop (no jet) to its own
reference (:func:`proxplan.verify.tracking.tracking_along_plan`,
:func:`proxplan.physics.tracking_response`: jerk and snap against the attitude and motor loops, the
set-point hold); the measured tube t covers what that linear model leaves out. (Not for an export
read back, ``proxplan.planfile.read_export``: its trajectories are already the uploads' predicted
flight, resampled every 50 ms, whose interpolant's jerk and snap the prediction would over-state.)
For every vehicle
the model predicts a disturbance on (:func:`proxplan.verify.wrench_along_plan`),
the jet's force and torque gradients with respect to its position are finite differences of the
one model (``proxplan.costmaps.sources_wrench``: the sources above it, their stack and the
scenario's between-vehicle effects; :func:`proxplan.physics.hover_loop.wrench_gradient`), and the
linearised loop of its controller in that jet (:mod:`proxplan.physics.hover_loop`) is driven along
the plan by the wrench and by its gradients acting on e (:func:`proxplan.physics.hover_loop.jet_response`).
Its tube grows by

    |e(t) + d(t)| + t gamma(t)                            (t = limits.tracking_margin_m, m)

d the deviation the jet adds, gamma the bound on how far the jet makes a deviation within the
tube grow (zero without a jet). After the plan's end every vehicle holds its final position: the hold's
bounds are part of the last sample. A vehicle whose loop is not damped where it holds at the end
(rightmost pole with real part >= 0) oscillates there however it is planned:
:func:`check_jet_loop` names it, the source and the margin. World frame, z up; m, N, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from proxplan.costmaps import sources_wrench
from proxplan.physics import (
    JetResponse,
    ModelOptions,
    TrackingResponse,
    Vehicle,
    jet_response,
    loop_matrices,
    loop_poles,
    one_blas_thread,
    weak_jet_bound_m,
    wrench_gradient,
)
from proxplan.planfile import PREDICTED_FLIGHT_KEY, Plan, Scenario
from proxplan.verify.along import Samples, WrenchAlongPlan, model_options, moving_mask
from proxplan.verify.reach import MIN_DZ_M
from proxplan.verify.tracking import tracking_along_plan
from proxplan.verify.violations import Violation

WEAK_USAGE = 1e-6
"""A source whose jet uses less than this share of a vehicle's authority at a sample (a millionth)
is left out of the jet's gradients there; a vehicle whose jets never reach it is not run through
the loop in the jet: its tube grows by the bound of what such a force and torque can do in its loop
without the jet (:func:`proxplan.physics.hover_loop.weak_jet_bound_m`, micrometres)."""


@dataclass(frozen=True)
class LoopAlongPlan:
    """One vehicle's loop along the plan: its ``response`` (:class:`proxplan.physics.hover_loop.
    JetResponse`; None for no jet or one too weak to matter, :data:`WEAK_USAGE`), its tube growth
    ``deflection_m`` (M,), m (|e + d| + t gamma, the hold in the last sample; the plan alone where
    the final loop is not damped), and ``source``: the vehicle whose jet acts on it most at the end
    (None: none)."""

    response: JetResponse | None
    deflection_m: np.ndarray
    source: str | None


def target_gradients(
    target: Vehicle,
    positions_m: np.ndarray,
    sources: list[tuple[Vehicle, np.ndarray]],
    options: ModelOptions,
    effects: tuple,
) -> tuple[np.ndarray, np.ndarray]:
    """Gradients (M, 3, 3) of the wrench on ``target`` at ``positions_m`` (M, 3), m, with respect to
    its position, N/m and N m/m, from ``sources`` (vehicle, positions (M, 3) m) together."""

    def wrench(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        reps = p.shape[0] // positions_m.shape[0]
        return sources_wrench(target, [(v, p - np.tile(q, (reps, 1))) for v, q in sources], options, effects)

    return wrench_gradient(wrench, positions_m)


@one_blas_thread
def loop_along_plan(
    plan: Plan, scenario: Scenario | None, along: dict, *, samples: Samples | None = None
) -> dict[str, LoopAlongPlan]:
    """Per vehicle of ``along``, its loop along the plan (:class:`LoopAlongPlan`);
    ``along``: :func:`proxplan.verify.wrench_along_plan` on a uniform grid from the plan's start;
    ``samples``: the plan's :data:`proxplan.verify.along.Samples` on that grid, if already taken.
    Run with one BLAS thread (:func:`proxplan.physics.one_blas_thread`: many small products)."""
    out: dict[str, LoopAlongPlan] = {}
    if not along:
        return out
    t = next(iter(along.values())).t_s
    pos = {n: s[0] for n, s in samples.items()} if samples is not None else plan.positions_at(t)
    opts = model_options(scenario)
    effects = tuple(scenario.effects if scenario is not None else plan.effects)
    tube = float(scenario.limits.tracking_margin_m) if scenario is not None else 0.0
    cap = _largest_growth_m(scenario, pos)
    flight = bool(plan.metrics.get(PREDICTED_FLIGHT_KEY))  # an export read back: no tracking prediction
    for name, w in along.items():
        track = (
            tracking_along_plan(plan.vehicles[name], t, samples=samples[name] if samples is not None else None)
            if not flight
            else TrackingResponse(t, np.zeros((t.size, 3)), 0.0)
        )
        e = np.linalg.norm(track.error_m, axis=1)
        hit = (np.abs(w.force_N).max(axis=1) > 0.0) | (np.abs(w.torque_Nm).max(axis=1) > 0.0)
        if not hit.any():
            size = e.copy()
            if size.size:
                size[-1] = max(size[-1], track.hold_error_m)
            out[name] = LoopAlongPlan(None, np.minimum(size, cap), None)
            continue
        vehicle = _vehicle(plan, scenario, name)
        last = {s: float(u[-1]) for s, u in w.usage_by_source.items()}
        source = max(last, key=lambda s: last[s]) if last and max(last.values()) > 0.0 else None
        if not (w.usage >= WEAK_USAGE).any():  # too weak a jet to matter: its bound
            bound = weak_jet_bound_m(
                vehicle,
                float(np.linalg.norm(w.force_N, axis=1).max()),
                float(np.linalg.norm(w.torque_Nm, axis=1).max()),
            )
            first = int(np.argmax(hit))  # from the first sample the jet reaches it on
            size = e + np.where(np.arange(t.size) >= first, bound, 0.0)
            size[-1] = max(size[-1], track.hold_error_m + bound)
            out[name] = LoopAlongPlan(None, np.minimum(size, cap), source)
            continue
        gf = np.zeros((t.size, 3, 3))
        gt = np.zeros((t.size, 3, 3))
        for key, rows in _source_sets(name, w, pos, t.size).items():  # those jets together (stacks), per set
            sources = [(_vehicle(plan, scenario, s), pos[s][rows]) for s in key]
            gf[rows], gt[rows] = target_gradients(vehicle, pos[name][rows], sources, opts, effects)
        moving = moving_mask(plan, [name], t, samples)[0]
        resp = jet_response(t, vehicle, w.force_N, w.torque_Nm, gf, gt, moving, track.error_m)
        size = np.linalg.norm(resp.deflection_m + track.error_m, axis=1) + tube * resp.tube_gain
        if np.isfinite(resp.hold_deflection_m):
            size[-1] = max(size[-1], resp.hold_deflection_m + tube * resp.hold_tube_gain + track.hold_error_m)
        out[name] = LoopAlongPlan(resp, np.minimum(size, cap), source)
    return out


def _source_sets(name: str, w, pos: dict[str, np.ndarray], m: int) -> dict[tuple[str, ...], np.ndarray]:
    """The samples (rows) where the jets on ``name`` matter (its authority usage >= :data:`WEAK_USAGE`),
    grouped by the set of sources that matter there: those whose own usage reaches it, else every
    vehicle above it (by more than 1e-6 m, as the checks count "above"; a usage no such source
    explains is the model's value at dz -> 0 of a source level with it, left without gradient)."""
    names = sorted(w.usage_by_source)
    ks = np.flatnonzero(w.usage >= WEAK_USAGE)
    which = np.stack([w.usage_by_source[s][ks] >= WEAK_USAGE for s in names]) if names else np.zeros((0, ks.size), bool)
    by_source = which.any(axis=0)
    others = [o for o in pos if o != name]
    rest = ks[~by_source]  # no source's own usage reaches it: every vehicle above (only these samples)
    z = pos[name][rest, 2]
    above = np.stack([pos[o][rest, 2] - z > MIN_DZ_M for o in others]) if others else np.zeros((0, rest.size), bool)
    groups: dict[tuple[str, ...], list[np.ndarray]] = {}
    for pattern, rows, labels in ((which[:, by_source], ks[by_source], names), (above, rest, others)):
        if not rows.size:
            continue
        kinds, inverse = np.unique(pattern.T, axis=0, return_inverse=True)
        for i, kind in enumerate(kinds):
            key = tuple(label for label, on in zip(labels, kind) if on)
            if key:
                groups.setdefault(key, []).append(rows[inverse.ravel() == i])
    return {key: np.sort(np.concatenate(parts)) for key, parts in groups.items()}


def _largest_growth_m(scenario: Scenario | None, pos: dict[str, np.ndarray]) -> float:
    """The largest tube growth worth stating, m: the workspace's diagonal (the plan's extent without
    a scenario). A linearised loop that grows beyond it has left its validity long before, and a
    tube that wide fails every check it enters anyway."""
    if scenario is not None:
        return float(np.linalg.norm(np.asarray(scenario.workspace_max_m) - np.asarray(scenario.workspace_min_m)))
    flat = np.concatenate([p.reshape(-1, 3) for p in pos.values()])
    return float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0))) + 1.0


def check_jet_loop(
    loops: dict[str, LoopAlongPlan], t_s: np.ndarray, plan_t_s: np.ndarray, far_m: float
) -> list[Violation]:
    """A violation for every vehicle whose loop is not damped where it holds at the end of the plan,
    and for every vehicle the loop is predicted to move off its plan by more than ``far_m`` (m, the
    scenario's ``min_separation_m``: as far as vehicles keep apart; a plan that holds or flies a
    vehicle where its jet undamps it long enough for that)."""
    out = []
    for name, lp in loops.items():
        if lp.deflection_m.size and float(lp.deflection_m.max()) > far_m:
            k = int(np.argmax(lp.deflection_m > far_m))
            out.append(
                Violation(
                    float(t_s[k]),
                    name,
                    "jet-loop",
                    f"its closed loop {f'in the jet of {lp.source}' if lp.source else 'on its own reference'} moves it "
                    "farther off its plan than the scenario's "
                    f"separation (up to {float(lp.deflection_m.max()):.3f} m beyond its tracking tube; m)",
                    float(lp.deflection_m.max()),
                    far_m,
                    int(np.clip(np.searchsorted(plan_t_s, t_s[k] + 1e-9, side="right") - 1, 0, plan_t_s.size - 1)),
                )
            )
        if lp.response is None:  # no jet, or one too weak to matter: the loop without it, damped
            continue
        growth = float(lp.response.poles.growth_ps[0])
        if growth < 0.0:
            continue
        freq = float(lp.response.poles.frequency_hz[0])
        out.append(
            Violation(
                float(t_s[-1]),
                name,
                "jet-loop",
                f"closed loop not damped in the jet of {lp.source} where it holds at the end: rightmost pole "
                f"{growth:+.3f} 1/s at {freq:.2f} Hz (margin {-growth:+.3f} 1/s; it oscillates however it is "
                "planned; move it out of that jet or retune its attitude loop)",
                growth,
                0.0,
                int(plan_t_s.size - 1),
            )
        )
    return out


def hold_poles(target: Vehicle, position_m: np.ndarray, sources: list[tuple[Vehicle, np.ndarray]],
               options: ModelOptions, effects: tuple) -> tuple[float, float]:  # fmt: skip
    """(growth 1/s, frequency Hz) of the rightmost pole of ``target``'s loop held at ``position_m``
    (3,), m, in the jets of ``sources`` (vehicle, position (3,) m), all at rest."""
    p = np.asarray(position_m, dtype=float).reshape(1, 3)
    srcs = [(v, np.asarray(q, dtype=float).reshape(1, 3)) for v, q in sources]
    force, torque = sources_wrench(target, [(v, p - q) for v, q in srcs], options, effects)
    gf, gt = target_gradients(target, p, srcs, options, effects)
    poles = loop_poles(loop_matrices(target, force, torque, gf, gt))
    return float(poles.growth_ps[0]), float(poles.frequency_hz[0])


def _vehicle(plan: Plan, scenario: Scenario | None, name: str) -> Vehicle:
    return scenario.vehicles[name].vehicle if scenario is not None else plan.vehicles[name].vehicle


def deflection_along_plan(
    plan: Plan, scenario: Scenario | None, along: dict[str, WrenchAlongPlan]
) -> dict[str, np.ndarray]:
    """Per vehicle how far (M,), m, it is predicted to leave its plan beyond its tracking tube,
    flying its own reference and in the jets the model predicts on it along the plan (``along``, on
    a uniform grid from the plan's start): :func:`loop_along_plan`'s growth (the hold after the
    plan's end in the last sample). Part of that vehicle's tube."""
    loops = loop_along_plan(plan, scenario, along)
    return {name: loops[name].deflection_m if name in loops else np.zeros(w.t_s.size) for name, w in along.items()}
