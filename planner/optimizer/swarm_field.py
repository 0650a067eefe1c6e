"""The direct model check of the decomposed optimisation: every vehicle's position on a check grid
and the total disturbance wrench on each (:class:`SwarmField`), and the workspace / obstacle and
kinematic checks of one candidate trajectory. As the verifier: separation and invalid zone with the
tracking tube while either vehicle moves, authority of the vehicle and of every vehicle in its jet,
summed over all sources (``proxplan.costmaps.pair_wrench``: S0-3..S0-8 plus the scenario's effects).
World frame, z up; m, s, N, N m."""

from __future__ import annotations

from collections.abc import Collection

import numpy as np

from proxplan.costmaps import pair_wrench
from proxplan.physics import ModelOptions, authority_usage, invalid_zone_mask
from proxplan.planfile import Plan
from proxplan.verify import REST_SPEED_MPS, tube_offsets

CHECK_DT_S = 0.02  # grid of the per-vehicle model check, s (the verifier re-checks at 0.01 s)


class SwarmField:
    """Every vehicle's position on a check grid and the total disturbance wrench on each (sum over
    all sources above it, ``proxplan.costmaps.pair_wrench``: S0-3..S0-8 plus the scenario's effects, as the
    verifier), updated as vehicles change; the non-zero pair contributions are kept."""

    def __init__(self, scenario, plan: Plan, *, dt_s: float = CHECK_DT_S):
        self.scenario = scenario
        self.options = ModelOptions(field_form=scenario.field_form) if scenario.field_form else ModelOptions()
        self.effects = tuple(getattr(scenario, "effects", ()))  # a calibrated model's, as the verifier
        self.t_s = np.arange(0.0, float(plan.t_s[-1]) + dt_s / 2, dt_s)
        self.pos = {n: tr.position_at(self.t_s) for n, tr in plan.vehicles.items()}
        self.vehicle = {n: scenario.vehicles[n].vehicle for n in plan.vehicles}
        self.names = list(plan.vehicles)
        m = self.t_s.size
        self.force = {n: np.zeros((m, 3)) for n in self.names}
        self.torque = {n: np.zeros((m, 3)) for n in self.names}
        # (source, target) -> its (force, torque) at the current positions; absent: zero
        self._pairs: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
        # contributions of the last candidate checked: (name, id(p_new), {key: (force, torque)})
        self._candidate: tuple[str, int, dict] | None = None
        for t in self.names:
            for s in self.names:
                if s != t:
                    self._store(s, t, self.contribution(s, t, self.pos[s], self.pos[t]))
                    f, q = self.current(s, t)
                    self.force[t] += f
                    self.torque[t] += q

    def _store(self, source: str, target: str, fq: tuple[np.ndarray, np.ndarray]) -> None:
        if np.any(fq[0]) or np.any(fq[1]):
            self._pairs[(source, target)] = fq
        else:
            self._pairs.pop((source, target), None)

    def current(self, source: str, target: str) -> tuple[np.ndarray, np.ndarray]:
        """(force_N, torque_Nm) (M, 3) of ``source`` on ``target`` at the current positions."""
        zero = np.zeros((self.t_s.size, 3))
        return self._pairs.get((source, target), (zero, zero))

    def contribution(self, source: str, target: str, p_source: np.ndarray, p_target: np.ndarray):
        """(force_N (M, 3), torque_Nm (M, 3)) of ``source`` on ``target`` at the given positions."""
        off = p_target - p_source
        f, q = np.zeros_like(off), np.zeros_like(off)
        below = -off[:, 2] > 1e-6
        if not self.effects:  # base model: a jet 6 m to the side is below 1e-6 of any authority
            below &= np.hypot(off[:, 0], off[:, 1]) < 6.0
        if below.any():
            f[below], q[below] = pair_wrench(
                self.vehicle[source], self.vehicle[target], off[below], self.options, self.effects
            )
        return f, q

    def tube_contribution(self, source: str, target: str, p_source: np.ndarray, p_target: np.ndarray, use):
        """As :meth:`contribution`, but where ``use`` (M,) holds with the target at the worst point of
        the tracking tube (``proxplan.verify.tube_offsets``, the verifier's authority-tube rule)."""
        f, q = self.contribution(source, target, p_source, p_target)
        tube = self.scenario.limits.tracking_margin_m
        off = p_target - p_source
        use = use & (-off[:, 2] > 1e-6)
        if tube <= 0.0 or not use.any():
            return f, q
        veh = self.vehicle[target]
        best_u = np.full(int(use.sum()), -np.inf)
        for o in tube_offsets(off[use], tube):
            fo, qo = pair_wrench(self.vehicle[source], veh, o, self.options, self.effects)
            u = authority_usage(veh, fo, qo)
            better = u > best_u
            best_u[better] = u[better]
            rows = np.flatnonzero(use)[better]
            f[rows], q[rows] = fo[better], qo[better]
        return f, q

    def usage(self, name: str) -> np.ndarray:
        return authority_usage(self.vehicle[name], self.force[name], self.torque[name])

    def conflicts(self, name: str, p_new: np.ndarray) -> tuple[np.ndarray, str | None]:
        """(mask (M,) of check times where ``name`` flying ``p_new`` (M, 3) breaks a pair rule, the
        first broken rule as text). Authority of another vehicle counts only where the change makes
        it worse than before and over the limit."""
        lim = self.scenario.limits
        frac = lim.authority_fraction
        me = self.vehicle[name]
        bad = np.zeros(self.t_s.size, dtype=bool)
        first: list[tuple[int, str]] = []

        def note(mask: np.ndarray, what: str) -> None:
            nonlocal bad
            if mask.any():
                bad |= mask
                first.append((int(np.argmax(mask)), what))

        force, torque = np.zeros_like(p_new), np.zeros_like(p_new)
        tube_force, tube_torque = np.zeros_like(p_new), np.zeros_like(p_new)  # the verifier's authority-tube rule
        new_pairs: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
        me_moving = self._moving(p_new)
        for o in self.names:
            if o == name:
                continue
            other = self.vehicle[o]
            off = p_new - self.pos[o]
            # the tracking tube while either vehicle of the pair moves, as the verifier checks
            tube = np.where(me_moving | self._moving(self.pos[o]), lim.tracking_margin_m, 0.0)  # (M,) m
            sep = max(lim.min_separation_m, me.body_radius_m + other.body_radius_m) + tube
            note(np.linalg.norm(off, axis=1) < sep, f"separation from {o}")
            if lim.invalid_zone_rule != "model":
                note(invalid_zone_mask(other, me, off, tube), f"invalid zone of {o}")
                note(invalid_zone_mask(me, other, -off, tube), f"invalid zone on {o}")
            f, q = new_pairs[(o, name)] = self.contribution(o, name, self.pos[o], p_new)
            force += f
            torque += q
            pair_moving = tube > 0.0
            ft, qt = self.tube_contribution(o, name, self.pos[o], p_new, pair_moving)
            tube_force += ft
            tube_torque += qt
            f_old, q_old = self.current(name, o)
            f_new, q_new = new_pairs[(name, o)] = self.contribution(name, o, p_new, self.pos[o])
            if np.any(f_new) or np.any(f_old):
                before = authority_usage(other, self.force[o], self.torque[o])
                after = authority_usage(other, self.force[o] - f_old + f_new, self.torque[o] - q_old + q_new)
                note((after > frac) & (after > before + 1e-9), f"authority of {o} in its jet")
                f_tb, q_tb = self.tube_contribution(name, o, p_new, self.pos[o], pair_moving)
                after_t = authority_usage(other, self.force[o] - f_old + f_tb, self.torque[o] - q_old + q_tb)
                note((after_t > frac) & (after_t > before + 1e-9), f"authority of {o} within the tube")
        note(authority_usage(me, force, torque) > frac, "authority")
        note(authority_usage(me, tube_force, tube_torque) > frac, "authority within the tube")
        self._candidate = (name, id(p_new), new_pairs)
        return bad, (min(first)[1] if first else None)

    def _moving(self, p: np.ndarray) -> np.ndarray:
        """(M,) bool: the vehicle at positions ``p`` (M, 3) on the check grid moves at least at the
        verifier's rest speed (proxplan.verify.REST_SPEED_MPS, m/s)."""
        speed = np.linalg.norm(np.gradient(p, self.t_s, axis=0), axis=1) if p.shape[0] > 1 else np.zeros(1)
        return speed >= REST_SPEED_MPS

    def replace(self, name: str, p_new: np.ndarray) -> None:
        """Move ``name`` onto ``p_new`` (M, 3) and update every affected wrench total."""
        known = self._candidate[2] if self._candidate and self._candidate[:2] == (name, id(p_new)) else {}
        force, torque = np.zeros_like(p_new), np.zeros_like(p_new)
        for o in self.names:
            if o == name:
                continue
            f, q = known.get((o, name)) or self.contribution(o, name, self.pos[o], p_new)
            force += f
            torque += q
            f_old, q_old = self.current(name, o)
            f_new, q_new = known.get((name, o)) or self.contribution(name, o, p_new, self.pos[o])
            self.force[o] += f_new - f_old
            self.torque[o] += q_new - q_old
            self._store(o, name, (f, q))
            self._store(name, o, (f_new, q_new))
        self.force[name], self.torque[name] = force, torque
        self.pos[name] = p_new
        self._candidate = None

    def at(self, name: str, t_s: np.ndarray) -> np.ndarray:
        """Positions (K, 3) of ``name`` at ``t_s`` (K,) by linear interpolation of the check grid."""
        p = self.pos[name]
        return np.column_stack([np.interp(t_s, self.t_s, p[:, i]) for i in range(3)])

    def wrench_at(self, name: str, t_s: np.ndarray, *, without: str | Collection[str]) -> np.ndarray:
        """Rows (F_z N, tau_x N m, tau_y N m) (3, K) on ``name`` at ``t_s`` from every source but
        ``without`` (the vehicle or vehicles being optimised)."""
        f, q = self.force[name].copy(), self.torque[name].copy()
        for w in [without] if isinstance(without, str) else without:
            f_w, q_w = self.current(w, name)
            f -= f_w
            q -= q_w
        cols = (f[:, 2], q[:, 0], q[:, 1])
        return np.vstack([np.interp(t_s, self.t_s, c) for c in cols])


def static_conflict(scenario, name: str, p: np.ndarray) -> str | None:
    """Workspace and obstacle breaches of the body disc at positions ``p`` (K, 3)."""
    task, lim = scenario.vehicles[name], scenario.limits
    rb, mz = task.vehicle.body_radius_m, lim.obstacle_margin_m
    lo = np.asarray(scenario.workspace_min_m) + np.array([rb, rb, mz])
    hi = np.asarray(scenario.workspace_max_m) - np.array([rb, rb, mz])
    if np.any(p < lo - 1e-9) or np.any(p > hi + 1e-9):
        return "workspace"
    for i, box in enumerate(scenario.obstacles):
        grow = np.array([rb + mz, rb + mz, mz])
        inside = np.all((p > box.min_m - grow) & (p < box.max_m + grow), axis=1)
        if inside.any():
            return f"obstacle[{i}]"
    return None


def kinematic_conflict(task, v: np.ndarray, a: np.ndarray, dt_s: float) -> str | None:
    if np.linalg.norm(v, axis=1).max() > task.max_speed_mps * 1.0:
        return "speed"
    if np.linalg.norm(a, axis=1).max() > task.max_accel_mps2 * 1.0:
        return "acceleration"
    if a.shape[0] > 1 and (np.linalg.norm(np.diff(a, axis=0), axis=1) / dt_s).max() > task.max_jerk_mps3 * 1.05:
        return "jerk"
    return None
