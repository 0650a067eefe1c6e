"""Whether swarm tracks pass the independent verifier (:func:`proxplan.verify.verify_plan`), for the
whole plan or only around tracks that changed.

The swarm layer plans against pair keep-outs, which do not see a sum: the verifier sums the jets of
every source above a vehicle (authority, authority within the tube, the closed loop in the jets).
The stacked plan's levels are stacked so that two sources at half the authority fraction fit
(:data:`proxplan.planner.swarm.levels.STACK_AUTHORITY_SHARE`); a track the makespan repair plans
again between two levels can put a second full jet on a vehicle below that is already under one
(grid-256: v118 0.58 m above v107 with v117 1.16 m above it, 0.119 of the 0.1 fraction; stop 59
round 21A). :class:`VerifyGuard` asks the verifier about the whole plan (called: the guard of the
makespan repair on the stacked plan, asked once after it), and filters the tracks the repair plans
again (:meth:`VerifyGuard.fits`): a track flown flat at a height its type does not fly flat at in
the plan the repair started from (its level, :func:`level_heights_m`) over a vehicle that is under
another source then (:func:`adds_a_height`, positions only) is taken only where the verifier's own
checks that sum the jets pass on a sub-plan around it (:meth:`VerifyGuard.around`, no second model):
the changed vehicle, the vehicles below it within reach while it differs from its old track (whose
sums it joins), and the sources above those and above it (:func:`near_agents`).

World frame, z up, m; tracks on the swarm grid (:data:`~proxplan.planner.swarm.tracks.GRID_DT_S`).
"""

from __future__ import annotations

import hashlib
import io
import pickle
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.swarm.frozen import apply_unfreezes
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.paths import TimedPath
from proxplan.verify import MIN_DZ_M

# the targets and sources of a change are the vehicles within this many times the problem's largest
# pair reach (problem.reach_xy_m, the full-fraction keep-out's horizontal reach, 0.40 m on the bench's
# types) of it, horizontally, at the same grid step. One reach, measured (stop 60 round 22A, grid-256's
# stacked plan replayed): the sub-plan fails where the whole plan fails (v107 under v117 and v118,
# 0.119 > 0.1) and the repaired plan whose 47 sub-plans passed passes the whole verifier; two reaches
# made the sub-plans 2-3 times larger (grid-128: 24-59 -> 70-108 vehicles) for the same answers
NEAR_REACHES = 1.0
# a changed track differs from its old one where the two are farther apart than this, m (below the
# keep-outs' millimetre rounding, problem.GROWTH_M: an unchanged stretch repeats the same samples)
MOVED_M = 1e-3
# a source is above a target when higher by more than this, m (the verifier's: verify.reach.MIN_DZ_M)
ABOVE_M = MIN_DZ_M

# a track flies on a level when within this of a height its type flies flat at (m): the stacked
# plan's levels are flat, every vehicle of a level at its height to the millimetre (grid-128 and
# grid-256: 0.92, 1.50, 2.08 m), and the stacking makes those heights' jets legal together, not a
# height between them (stop 60 round 22A); 1 cm, half the keep-out tables' dz step (2 cm)
LEVEL_DZ_M = 0.01

# the sums of jets are checked at this time step, s (verify_plan's default dt_fine_s)
FINE_DT_S = 0.01

# whether tracks (agent -> track) pass the verifier
Check = Callable[[Mapping[int, GridTrack]], bool]

__all__ = [
    "ABOVE_M",
    "FINE_DT_S",
    "LEVEL_DZ_M",
    "adds_a_height",
    "level_heights_m",
    "MOVED_M",
    "NEAR_REACHES",
    "Check",
    "VerifyGuard",
    "near_agents",
]


def _passes(scenario: Scenario, timed: Mapping[str, TimedPath]) -> bool:
    from proxplan.planner.timing.plan_grid import assemble_plan
    from proxplan.verify import verify_plan

    plan = assemble_plan(scenario, dict(timed), method="swarm", notes=[])
    return not verify_plan(plan, scenario)


def level_heights_m(tracks: Mapping[int, GridTrack]) -> np.ndarray:
    """The heights (m, sorted, to :data:`LEVEL_DZ_M`) at which ``tracks`` fly horizontally (a grid
    step that moves horizontally and not vertically): the levels of a stacked plan (its vertical
    moves at the start and the end pass through every height, but never horizontally)."""
    z = [t.positions_m[1:, 2][_flat(t)] for t in tracks.values()]
    allz = np.concatenate(z) if z else np.zeros(0)
    return np.unique(np.round(allz / LEVEL_DZ_M)) * LEVEL_DZ_M


def _flat(track: GridTrack) -> np.ndarray:
    """(n,) True on the grid steps k -> k + 1 of ``track`` that move horizontally and not vertically."""
    d = np.diff(track.positions_m, axis=0)
    return (np.abs(d[:, 2]) <= ABOVE_M) & (np.hypot(d[:, 0], d[:, 1]) > ABOVE_M)


def adds_a_height(others: Mapping[int, GridTrack], track: GridTrack, radius_m: float, level_z_m: np.ndarray) -> bool:
    """Whether ``track`` flies horizontally at a height off the levels ``level_z_m`` (farther than
    :data:`LEVEL_DZ_M` from each, m) above a vehicle of ``others`` (agent -> track; by more than
    :data:`ABOVE_M`, within ``radius_m`` horizontally, at the same grid step, parked tracks at their
    ends) that has another source above it within ``radius_m`` then: a second jet from a height the
    stacking did not make legal (see module). Positions only: the filter before the verifier
    (:meth:`VerifyGuard.around`), m."""
    off = np.zeros(track.positions_m.shape[0], dtype=bool)
    z_track = track.positions_m[1:, 2]
    gap = np.abs(z_track[:, None] - np.asarray(level_z_m)[None, :]).min(axis=1, initial=np.inf) > LEVEL_DZ_M
    off[1:] = _flat(track) & gap
    if not off.any():
        return False
    steps = np.flatnonzero(off)
    box = track.positions_m[steps]
    lo, hi = box[:, :2].min(axis=0) - radius_m, box[:, :2].max(axis=0) + radius_m
    near = [
        t
        for b, t in sorted(others.items())
        if b != track.agent and not (np.any(t.lo_m[:2] > hi) or np.any(t.hi_m[:2] < lo))
    ]
    if len(near) < 2:
        return False
    mine = track.positions_m[steps]  # (S, 3), m
    pos = np.stack([t.position_at_steps(steps) for t in near])  # (K, S, 3), m
    r2 = radius_m * radius_m
    d = pos[:, :, :2] - mine[None, :, :2]
    under = (np.einsum("ksj,ksj->ks", d, d) <= r2) & (mine[None, :, 2] > pos[:, :, 2] + ABOVE_M)
    z = pos[:, :, 2]
    for k in np.flatnonzero(under.any(axis=1)):  # a vehicle below it: under another source then?
        when = under[k]
        dc = pos[:, when, :2] - pos[k, when, :2][None]
        if bool(np.any((np.einsum("ksj,ksj->ks", dc, dc) <= r2) & (z[:, when] > z[k, when][None] + ABOVE_M))):
            return True
    return False


def near_agents(
    by_agent: Mapping[int, GridTrack], old: Mapping[int, GridTrack | None], radius_m: float
) -> tuple[set[int], set[int], np.ndarray]:
    """The agents whose sums of jets a change can alter, and the other sources of those sums (see
    module): for each agent of ``old`` (its track before the change; None: it had none), the steps
    where its track in ``by_agent`` differs from the old one by more than :data:`MOVED_M`; the
    *targets*: agents below it (by more than :data:`ABOVE_M`) within ``radius_m`` horizontally at
    one of those steps; the *sources*: agents above a target within ``radius_m`` of it at a step
    where it is under a changed track, and agents above a changed track within ``radius_m`` at a
    step where it differs. Returns the targets, the sources (neither holds a changed agent) and the
    steps where some changed track differs (bool per step from 0). Parked tracks at their ends; m,
    grid steps."""
    agents = sorted(by_agent)
    end = max(t.arrival_step for t in by_agent.values())
    for track in old.values():
        if track is not None:
            end = max(end, track.arrival_step)
    steps = np.arange(end + 1)
    pos = np.stack([by_agent[a].position_at_steps(steps) for a in agents])  # (A, T, 3), m
    xy, z = pos[:, :, :2], pos[:, :, 2]
    r2 = radius_m * radius_m
    under = np.zeros((len(agents), steps.size), dtype=bool)  # (A, T): below a changed track, within reach
    over = np.zeros(len(agents), dtype=bool)  # above a changed track within reach, where it differs
    differs = np.zeros(steps.size, dtype=bool)
    for a, before in old.items():
        mine = by_agent[a].position_at_steps(steps)
        moved = (
            np.ones(steps.size, dtype=bool)
            if before is None
            else np.linalg.norm(mine - before.position_at_steps(steps), axis=1) > MOVED_M
        )
        differs |= moved
        d = xy[:, moved] - mine[None, moved, :2]
        close = np.einsum("atk,atk->at", d, d) <= r2
        under[:, moved] |= close & (z[:, moved] < mine[None, moved, 2] - ABOVE_M)
        over |= (close & (z[:, moved] > mine[None, moved, 2] + ABOVE_M)).any(axis=1)
    sources = over.copy()
    for c in np.flatnonzero(under.any(axis=1)):
        when = under[c]
        d = xy[:, when] - xy[c, when][None]
        sources |= ((np.einsum("atk,atk->at", d, d) <= r2) & (z[:, when] > z[c, when][None] + ABOVE_M)).any(axis=1)
    changed = set(old)
    targets = {agents[k] for k in np.flatnonzero(under.any(axis=1)).tolist()} - changed
    return targets, {agents[k] for k in np.flatnonzero(sources).tolist()} - changed - targets, differs


def _sub_plan_key(keep: list[int], by_agent: Mapping[int, GridTrack], end_step: int, looped: list[int]) -> bytes:
    """What :meth:`VerifyGuard.around`'s verdict depends on (its scenario aside, the guard's own): the
    agents of the sub-plan, each one's track as its timed path is built from it (start and moves:
    :meth:`GridTrack.timed_path`), the last grid step checked and the agents whose loops run. Moves
    pickle as the arguments they are rebuilt from, deterministically (``Profile.__reduce__``,
    ``RunMove.__reduce__``), so equal keys give equal sub-plans; tracks equal but pickled otherwise
    only miss the memo (round 25A: corridor-64 asked 3 of its 23 sub-plans twice)."""
    tracks = [(a, np.asarray(by_agent[a].start_m, dtype=float), list(by_agent[a].moves)) for a in keep]
    out = io.BytesIO()
    pickler = _KeyPickler(out, protocol=pickle.HIGHEST_PROTOCOL)
    pickler.fast = True  # no memo: an object held twice is written twice, as two equal objects are
    pickler.dump((tracks, end_step, looped))
    return hashlib.sha256(out.getvalue()).digest()


class _KeyPickler(pickle.Pickler):
    """Pickles arrays by their dtype, shape and values only (not how they are held in memory: an array
    read back from a pickle pickles otherwise by default)."""

    def reducer_override(self, obj):
        if isinstance(obj, np.ndarray):
            return np.ndarray, (obj.shape, obj.dtype.str, np.ascontiguousarray(obj).tobytes())
        return NotImplemented


@dataclass
class VerifyGuard:
    """Whether tracks of ``problem`` (agent -> track) pass the verifier on ``scenario`` as the pipeline
    will verify them (the unfreeze steps of ``original`` applied first, :mod:`proxplan.planner.swarm.frozen`):
    called, about the whole plan (the guard of the makespan repair on the stacked plan); :meth:`around`,
    about the vehicles within reach of changed tracks only (see module). Counts what it was asked
    (``whole`` / ``whole_failed``, ``local`` / ``local_failed``, ``sizes``: the vehicles of each sub-plan;
    ``recalled``: the sub-plans asked again, answered by its memo of verdicts, :func:`_sub_plan_key`)."""

    scenario: Scenario
    problem: SwarmProblem
    original: SwarmProblem
    unfreezes: tuple = ()
    whole: int = 0
    whole_failed: int = 0
    local: int = 0
    local_failed: int = 0
    sizes: list[int] = field(default_factory=list)
    refused: int = 0
    recalled: int = 0  # sub-plans answered by the memo of verdicts (of ``local``)
    _verdicts: dict[bytes, bool] = field(default_factory=dict, repr=False)  # _sub_plan_key -> verdict
    _levels: dict[int, np.ndarray] | None = field(default=None, repr=False)  # type -> its levels, m
    _paths: dict[int, tuple[GridTrack, TimedPath]] = field(default_factory=dict, repr=False)

    def __call__(self, by_agent: Mapping[int, GridTrack]) -> bool:
        """Whether the tracks of ``by_agent`` pass the whole verifier: every agent's, or, with agents
        left out (not flying, as in :meth:`around`: the members of a neighbourhood of the makespan
        repair not planned again yet), those in place on the scenario without the others (round 32A:
        :meth:`around`'s answer to a change that moves nothing, asked in such a neighbourhood, looked
        up the agents left out and raised a KeyError)."""
        self.whole += 1
        names = [self.problem.names[a] for a in sorted(by_agent)]
        scenario = self.scenario
        if len(names) < self.problem.n_agents:
            scenario = replace(scenario, vehicles={n: scenario.vehicles[n] for n in names})
        ok = _passes(scenario, self._timed(by_agent))
        self.whole_failed += not ok
        return ok

    def around(self, by_agent: Mapping[int, GridTrack], old: Mapping[int, GridTrack | None]) -> bool:
        """Whether the verifier's checks that sum the jets (``separation`` / ``invalid-zone`` with the
        predicted deflections, ``authority``, ``authority-tube``: :func:`proxplan.verify.checks.check_pairs`,
        :func:`~proxplan.verify.checks.check_authority`, :func:`~proxplan.verify.checks.check_authority_tube`,
        the deflections of :func:`proxplan.verify.jet_loop.loop_along_plan`) pass on the sub-plan of the
        changed agents (``old``: agent -> its track before the change, their new tracks in ``by_agent``,
        which holds the tracks in place: agents left out are not flying) and the agents within reach of
        the change (:func:`near_agents`, :data:`NEAR_REACHES`: the targets below the changed tracks and
        the sources above those), from the start until the last step where a changed track differs, at
        :data:`FINE_DT_S`. The loops run for the changed agents and the targets only (the other sources'
        own sums are not whole in the sub-plan, so they are checked with no deflection, which only
        lowers what they use). With
        unfreeze steps (which shift every path) it passes everything to the whole plan's check; a change
        that moves no track by more than :data:`MOVED_M` is judged by the whole plan's check of the
        tracks in ``by_agent`` (:meth:`__call__`)."""
        from proxplan.planner.timing.plan_grid import assemble_plan
        from proxplan.verify import (
            check_authority,
            check_authority_tube,
            check_pairs,
            loop_along_plan,
            plan_samples,
            wrench_along_plan,
        )

        if self.unfreezes:
            return True
        targets, sources, differs = near_agents(by_agent, old, NEAR_REACHES * self.problem.reach_xy_m)
        if not differs.any():
            # no changed track moves by more than MOVED_M: no step bounds a sub-plan, and the change is
            # judged on the whole plan of the tracks in place (agents left out are not flying)
            return self(by_agent)
        self.local += 1
        keep = sorted(set(old) | targets | sources)
        self.sizes.append(len(keep))
        end = int(np.flatnonzero(differs)[-1])
        looped_agents = sorted(set(old) | targets)
        key = _sub_plan_key(keep, by_agent, end, looped_agents)
        known = self._verdicts.get(key)
        if known is not None:  # the same sub-plan asked before (a neighbourhood's track planned again alike)
            self.recalled += 1
            self.local_failed += not known
            return known
        names = [self.problem.names[a] for a in keep]
        sub = replace(self.scenario, vehicles={n: self.scenario.vehicles[n] for n in names})
        timed = {self.problem.names[a]: self._path(a, by_agent[a]) for a in keep}
        plan = assemble_plan(sub, timed, method="swarm", notes=[])
        t = np.arange(0.0, end * GRID_DT_S + FINE_DT_S / 2, FINE_DT_S)
        samples = plan_samples(plan, t)
        along = wrench_along_plan(plan, sub, t_s=t, samples=samples)
        looped = {self.problem.names[a] for a in looped_agents}
        loops = loop_along_plan(plan, sub, {n: w for n, w in along.items() if n in looped}, samples=samples)
        far = self.scenario.limits.min_separation_m  # as the verifier clips them
        deflection = {n: np.minimum(loops[n].deflection_m, far) if n in loops else np.zeros(t.size) for n in names}
        out = check_pairs(plan, sub, t, samples, deflection)
        out += check_authority(sub, t, along, plan.t_s)
        out += check_authority_tube(plan, sub, t, samples, deflection)
        self.local_failed += bool(out)
        self._verdicts[key] = not out
        return not out

    def fits(self, occ: Occupancy, track: GridTrack, old: GridTrack | None) -> bool:
        """Whether ``track`` (planned again; ``old``: that vehicle's track before, None: none) may join
        the tracks of ``occ``: where it adds a second jet over a vehicle from a height its type does not
        fly flat at in the plan the repair started from (its level; :func:`adds_a_height`, within the
        problem's pair reach), only where the verifier's sums pass around it (:meth:`around`). The
        makespan repair's filter on the stacked plan. Counts the tracks it refused (``refused``)."""
        if self._levels is None:  # each type's levels, from the tracks the repair starts from
            kinds = self.problem.type_index
            self._levels = {
                int(k): level_heights_m({a: t for a, t in occ.tracks.items() if kinds[a] == k})
                for k in set(kinds.tolist())
            }
        levels = self._levels.get(int(self.problem.type_index[track.agent]), np.zeros(0))
        if track is old or not adds_a_height(occ.tracks, track, self.problem.reach_xy_m, levels):
            return True
        ok = self.around({**occ.tracks, track.agent: track}, {track.agent: old})
        self.refused += not ok
        return ok

    def _path(self, a: int, track: GridTrack) -> TimedPath:
        """``track``'s timed path (agent ``a``), built once per track."""
        got = self._paths.get(a)
        if got is None or got[0] is not track:
            got = self._paths[a] = (track, track.timed_path())
        return got[1]

    def _timed(self, by_agent: Mapping[int, GridTrack]) -> dict[str, TimedPath]:
        """The timed path of every vehicle of ``by_agent`` as the pipeline will verify it (each track's path
        built once); with unfreeze steps (which shift every path) ``by_agent`` must hold every agent."""
        timed = {self.problem.names[a]: self._path(a, by_agent[a]) for a in sorted(by_agent)}
        if self.unfreezes:
            if len(timed) < self.problem.n_agents:
                raise ValueError("the unfreeze steps are applied to the whole plan only")
            timed, _ = apply_unfreezes(timed, self.original, self.unfreezes, GRID_DT_S)
        return timed
