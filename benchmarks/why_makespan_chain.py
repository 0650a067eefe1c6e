"""What holds the vehicles that set a swarm plan's makespan, read from a plan.json (issue 37, round 18C).

For every vehicle that arrives within ``--within`` s of the makespan: when it leaves its start, how long
its path is against its straight line (a detour), and every wait on the way (speed below
``STILL_MPS`` for at least ``MIN_WAIT_S``, away from its start and goal): where (distance short of its
goal) and who holds it. The *holder* of a wait is the other vehicle nearest (horizontally) to the
rest of the waiting vehicle's straight line (from where it waits to its goal) in the middle of the
wait; if the holder is itself waiting then, its holder is followed in turn (a chain), until a vehicle
that is not waiting: parked at its goal (goal-blocking), parked at its start (not left yet), or moving
(a passage shared in series). A late departure is reported with the vehicle nearest to the start's
straight line at the departure. Geometry only (the plan's samples): no keep-out is read, so
"nearest" is a pointer for a reader, not a proof of what the planner saw.

    cd /tmp && python /path/to/benchmarks/why_makespan_chain.py PLAN.json [--within 0.5]
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

STILL_MPS = 0.02  # below this speed a vehicle is at rest, m/s (the plan's samples are exact at rest: 0)
MIN_WAIT_S = 0.2  # a rest shorter than this is not reported as a wait, s (4 samples of 0.05 s)
AT_END_M = 0.05  # within this of its start or goal a vehicle is parked there, not waiting on the way, m
MAX_CHAIN = 8  # holders followed at most


def _seg_dist_xy(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Horizontal distance of points ``p`` (N, 3) to the segment a-b, m."""
    a, b, p = a[:2], b[:2], p[:, :2]
    d = b - a
    L2 = float(d @ d)
    u = np.zeros(len(p)) if L2 == 0 else np.clip((p - a) @ d / L2, 0.0, 1.0)
    return np.linalg.norm(p - (a + u[:, None] * d), axis=1)


class Plan:
    def __init__(self, path: str):
        d = json.load(open(path))
        self.names = sorted(d["vehicles"])
        v0 = d["vehicles"][self.names[0]]
        self.t = np.asarray(v0["t_s"])
        n = len(self.t)
        self.p = np.zeros((len(self.names), n, 3))
        self.v = np.zeros((len(self.names), n))
        for i, name in enumerate(self.names):
            v = d["vehicles"][name]
            pos, vel = np.asarray(v["position_m"]), np.asarray(v["velocity_mps"])
            m = len(pos)  # a plan.json pads every vehicle to the makespan, but be safe
            self.p[i, :m], self.p[i, m:] = pos, pos[-1]
            self.v[i, :m] = np.linalg.norm(vel, axis=1)
        self.start, self.goal = self.p[:, 0], self.p[:, -1]
        self.dt = float(self.t[1] - self.t[0])
        self.makespan = float(d["metrics"].get("makespan_s", self.t[-1]))
        self.lb = d["metrics"].get("certified_lower_bound_s") or d["metrics"].get("lower_bound_s")

    def arrival(self, i: int) -> float:
        far = np.nonzero(np.linalg.norm(self.p[i] - self.goal[i], axis=1) > 1e-4)[0]
        return float(self.t[far[-1] + 1]) if len(far) else 0.0

    def departure(self, i: int) -> float:
        moved = np.nonzero(np.linalg.norm(self.p[i] - self.start[i], axis=1) > 1e-4)[0]
        return float(self.t[max(0, moved[0] - 1)]) if len(moved) else 0.0

    def state(self, i: int, k: int) -> str:
        if np.linalg.norm(self.p[i, k] - self.goal[i]) < AT_END_M:
            return "at its goal"
        if np.linalg.norm(self.p[i, k] - self.start[i]) < AT_END_M:
            return "at its start"
        return "waiting on the way" if self.v[i, k] < STILL_MPS else "moving"

    def waits(self, i: int) -> list[tuple[int, int]]:
        """(first, last) sample of each rest on the way of vehicle i."""
        still = self.v[i] < STILL_MPS
        away = (np.linalg.norm(self.p[i] - self.goal[i], axis=1) > AT_END_M) & (
            np.linalg.norm(self.p[i] - self.start[i], axis=1) > AT_END_M
        )
        on = still & away
        out, k = [], 0
        while k < len(on):
            if on[k]:
                j = k
                while j + 1 < len(on) and on[j + 1]:
                    j += 1
                if (j - k + 1) * self.dt >= MIN_WAIT_S:
                    out.append((k, j))
                k = j + 1
            else:
                k += 1
        return out

    def holder(self, i: int, k: int) -> tuple[int, float]:
        """The other vehicle nearest (horizontally) to the rest of i's straight line at sample k."""
        d = _seg_dist_xy(self.p[:, k], self.p[i, k], self.goal[i])
        d[i] = np.inf
        j = int(np.argmin(d))
        return j, float(d[j])

    def chain(self, i: int, k: int) -> list[str]:
        seen, out = {i}, []
        for _ in range(MAX_CHAIN):
            j, dist = self.holder(i, k)
            st = self.state(j, k)
            out.append(f"{self.names[j]} ({dist:.2f} m off the line, {st}, arrives {self.arrival(j):.2f} s)")
            if st != "waiting on the way" or j in seen:
                break
            seen.add(j)
            i = j
        return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("plan")
    ap.add_argument("--within", type=float, default=0.5, help="vehicles arriving within this of the makespan, s")
    args = ap.parse_args()
    P = Plan(args.plan)
    arr = np.array([P.arrival(i) for i in range(len(P.names))])
    end = float(arr.max())
    lb = f", {end / P.lb:.2f}x the bound {P.lb:.2f} s" if P.lb else ""
    print(f"{args.plan}: makespan {end:.2f} s{lb}; {len(P.names)} vehicles")
    kinds: dict[str, int] = {}
    for i in np.argsort(-arr, kind="stable"):
        if arr[i] < end - args.within:
            break
        straight = float(np.linalg.norm(P.goal[i] - P.start[i]))
        length = float(np.linalg.norm(np.diff(P.p[i], axis=0), axis=1).sum())
        dep = P.departure(i)
        print(
            f"  {P.names[i]}: arrives {arr[i]:.2f} s, leaves {dep:.2f} s, path {length:.2f} m / straight "
            f"{straight:.2f} m ({length / max(straight, 1e-9):.2f}x)"
        )
        if dep > MIN_WAIT_S:
            k = int(round(dep / P.dt))
            d = _seg_dist_xy(P.p[:, k], P.start[i], P.goal[i])
            d[i] = np.inf
            j = int(np.argmin(d))
            print(f"    late departure: nearest to its line then {P.names[j]} ({d[j]:.2f} m, {P.state(j, k)})")
            kinds["late departure"] = kinds.get("late departure", 0) + 1
        for k0, k1 in P.waits(i):
            mid = (k0 + k1) // 2
            short = float(np.linalg.norm(P.goal[i] - P.p[i, mid]))
            ch = P.chain(i, mid)
            print(
                f"    waits {P.t[k0]:.2f}-{P.t[k1]:.2f} s, {short:.2f} m short of its goal; held by " + " <- ".join(ch)
            )
            last = ch[-1]
            kind = (
                "goal-blocking"
                if "at its goal" in last
                else "not left yet"
                if "at its start" in last
                else "passage in series"
            )
            kinds[kind] = kinds.get(kind, 0) + 1
    print("  kinds (chain ends): " + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
