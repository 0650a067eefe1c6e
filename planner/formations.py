"""Formation-change scenarios of N vehicles (the swarm benchmarks of issues 14 and 21).

``formation_change`` (two layers around a pillar, below), ``grid_reshuffle`` (a grid whose
vehicles swap slots by a seeded permutation), ``circle_swap`` (a circle where every vehicle flies to
the antipode, so every path crosses the centre) and ``corridor`` (two groups trading sides through
a gap in a wall); ``LAYOUTS`` maps their names to the functions, and :func:`layout_doc` builds one with
its goal assignment.

Two staggered layers ``layer_gap_m`` apart on the west side of a pillar; every vehicle flies to the
*other* layer on the east side (the slot mirrored across the pillar), so each crosses the others'
jets. Types cycle through ``types`` (default Crazyflie 2.1, Crazyflie-Parrot, S0 small quad).
World frame, z up, m.

    python -m proxplan.planner.formations 32 --out out/formation-32.yaml
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence
from typing import Any

DEFAULT_TYPES = ("crazyflie-2.1", "crazyflie-parrot", "small-quad")
LOW_Z_M = 1.0  # height of the lower layer, m
# the randomised family (random_formation): ranges its seeded draws come from
FAMILY_PITCH_M = (0.55, 0.9)  # slot pitch within a layer, m
FAMILY_LAYERS = (1, 2, 3)  # layers of a region (staggered by half a pitch)
FAMILY_LAYER_GAP_M = (0.4, 0.8)  # height between layers, m
FAMILY_OBSTACLES = (0, 3)  # boxes between the start and goal regions (inclusive range)
FAMILY_REGION_GAP_M = (0.0, 3.0)  # horizontal gap between the start and goal regions, m
FAMILY_DRAWS = 20  # draws per seed until the pre-checks pass (starts and goals valid)


def formation_change(
    n_vehicles: int,
    *,
    spacing_m: float = 0.6,
    layer_gap_m: float = 0.5,
    pillar_clearance_m: float = 0.8,
    types: Sequence[str] = DEFAULT_TYPES,
    authority_fraction: float = 0.1,
    min_separation_m: float = 0.25,
) -> dict[str, Any]:
    """The scenario mapping (DESIGN.md section 4) of an N-vehicle formation change.

    Slots: layer L (0 low, 1 high), row r (distance from the pillar), column c; a slot's x is
    -(pillar_clearance + r spacing) on the west side (mirrored on the east), y is centred columns;
    the high layer is staggered by half a spacing in x and y. Vehicle i starts in layer i % 2 and
    ends in the other layer, same row and column, east side.
    """
    if n_vehicles < 1:
        raise ValueError(f"a formation needs at least one vehicle, got {n_vehicles}")
    per_layer = math.ceil(n_vehicles / 2)
    cols = math.ceil(math.sqrt(per_layer))
    rows = math.ceil(per_layer / cols)

    def slot(layer: int, k: int, side: float) -> list[float]:
        row, col = divmod(k, cols)
        stagger = 0.5 * spacing_m * layer
        x = side * (pillar_clearance_m + row * spacing_m + stagger)
        y = (col - 0.5 * (cols - 1)) * spacing_m + stagger
        return [round(x, 4), round(y, 4), round(LOW_Z_M + layer * layer_gap_m, 4)]

    vehicles = {}
    for i in range(n_vehicles):
        layer, k = i % 2, i // 2
        vehicles[f"v{i:03d}"] = {
            "type": types[i % len(types)],
            "start": slot(layer, k, -1.0),
            "goal": slot(1 - layer, k, +1.0),
        }
    half_x = pillar_clearance_m + rows * spacing_m + 1.0
    half_y = 0.5 * cols * spacing_m + 1.0
    return {
        "name": f"formation-{n_vehicles}",
        "workspace": {"min": [-half_x, -half_y, 0.0], "max": [half_x, half_y, LOW_Z_M + layer_gap_m + 1.5]},
        "obstacles": [{"name": "pillar", "min": [-0.2, -0.2, 0.0], "max": [0.2, 0.2, LOW_Z_M + layer_gap_m + 1.0]}],
        "limits": {"authority_fraction": authority_fraction, "min_separation_m": min_separation_m},
        "vehicles": vehicles,
    }


def _types(i: int, types: Sequence[str]) -> str:
    return types[i % len(types)]


def _limits_block(authority_fraction: float, min_separation_m: float) -> dict[str, float]:
    return {"authority_fraction": authority_fraction, "min_separation_m": min_separation_m}


def grid_reshuffle(
    n_vehicles: int,
    *,
    spacing_m: float = 0.6,
    seed: int = 0,
    types: Sequence[str] = DEFAULT_TYPES,
    authority_fraction: float = 0.1,
    min_separation_m: float = 0.25,
) -> dict[str, Any]:
    """N vehicles on a square grid at 1.5 m height (``spacing_m`` apart, m) each fly to another
    slot of the same grid (a permutation from ``seed``)."""
    import numpy as np

    if n_vehicles < 1:
        raise ValueError(f"a layout needs at least one vehicle, got {n_vehicles}")
    cols = math.ceil(math.sqrt(n_vehicles))
    slots = [
        [round((c - 0.5 * (cols - 1)) * spacing_m, 4), round((r - 0.5 * (cols - 1)) * spacing_m, 4), 1.5]
        for r in range(cols)
        for c in range(cols)
    ][:n_vehicles]
    perm = np.random.default_rng(seed).permutation(n_vehicles)
    vehicles = {
        f"v{i:03d}": {"type": _types(i, types), "start": slots[i], "goal": slots[int(perm[i])]}
        for i in range(n_vehicles)
    }
    half = 0.5 * cols * spacing_m + 1.0
    return {
        "name": f"grid-reshuffle-{n_vehicles}",
        "workspace": {"min": [-half, -half, 0.0], "max": [half, half, 3.0]},
        "limits": _limits_block(authority_fraction, min_separation_m),
        "vehicles": vehicles,
    }


def circle_swap(
    n_vehicles: int,
    *,
    arc_spacing_m: float = 0.6,
    types: Sequence[str] = DEFAULT_TYPES,
    authority_fraction: float = 0.1,
    min_separation_m: float = 0.25,
) -> dict[str, Any]:
    """N vehicles on a circle (radius so that neighbours are ``arc_spacing_m`` apart, at least
    1.5 m), alternately at 1.0 m and 1.5 m height, each flying to the antipodal slot."""
    if n_vehicles < 1:
        raise ValueError(f"a layout needs at least one vehicle, got {n_vehicles}")
    radius = max(1.5, n_vehicles * arc_spacing_m / (2.0 * math.pi))
    vehicles = {}
    for i in range(n_vehicles):
        a = 2.0 * math.pi * i / n_vehicles
        z = 1.0 if i % 2 == 0 else 1.5
        start = [round(radius * math.cos(a), 4), round(radius * math.sin(a), 4), z]
        goal = [round(-radius * math.cos(a), 4), round(-radius * math.sin(a), 4), z]
        vehicles[f"v{i:03d}"] = {"type": _types(i, types), "start": start, "goal": goal}
    half = radius + 1.0
    return {
        "name": f"circle-swap-{n_vehicles}",
        "workspace": {"min": [-half, -half, 0.0], "max": [half, half, 3.0]},
        "limits": _limits_block(authority_fraction, min_separation_m),
        "vehicles": vehicles,
    }


def corridor(
    n_vehicles: int,
    *,
    spacing_m: float = 0.6,
    gap_m: float = 1.6,
    types: Sequence[str] = DEFAULT_TYPES,
    authority_fraction: float = 0.1,
    min_separation_m: float = 0.25,
) -> dict[str, Any]:
    """Two groups on either side of a wall (x = 0) with a ``gap_m`` wide corridor at y = 0 trade
    sides: the west group (a grid at 1.0 m height) flies to the east grid and back the other way
    (east group at 1.5 m height)."""
    if n_vehicles < 1:
        raise ValueError(f"a layout needs at least one vehicle, got {n_vehicles}")
    per_side = math.ceil(n_vehicles / 2)
    cols = math.ceil(math.sqrt(per_side))
    vehicles = {}
    for i in range(n_vehicles):
        side, k = (-1.0 if i % 2 == 0 else 1.0), i // 2
        row, col = divmod(k, cols)
        x = side * (1.0 + row * spacing_m)
        y = (col - 0.5 * (cols - 1)) * spacing_m
        z = 1.0 if side < 0 else 1.5
        vehicles[f"v{i:03d}"] = {
            "type": _types(i, types),
            "start": [round(x, 4), round(y, 4), z],
            "goal": [round(-x, 4), round(y, 4), z],
        }
    half_x = 1.0 + cols * spacing_m + 1.0
    half_y = max(0.5 * cols * spacing_m + 1.0, 0.5 * gap_m + 1.0)
    wall = 0.2
    return {
        "name": f"corridor-{n_vehicles}",
        "workspace": {"min": [-half_x, -half_y, 0.0], "max": [half_x, half_y, 3.0]},
        "obstacles": [
            {"name": "wall-south", "min": [-wall, -half_y, 0.0], "max": [wall, -0.5 * gap_m, 3.0]},
            {"name": "wall-north", "min": [-wall, 0.5 * gap_m, 0.0], "max": [wall, half_y, 3.0]},
        ],
        "limits": _limits_block(authority_fraction, min_separation_m),
        "vehicles": vehicles,
    }


def random_formation(n_vehicles: int, *, seed: int = 0) -> dict[str, Any]:
    """A seeded random formation change (the bench's family of layouts nobody tuned on): a start
    region and a goal region, each a grid of slots at a random pitch in 1-3 staggered layers,
    rotated at random and placed a random gap apart; 0-3 random boxes between them; a random mix of
    the built-in types; every vehicle to a random goal slot. A draw whose starts or goals break the
    planner's pre-checks (separation, cut-offs at rest) is drawn again from the same generator, up
    to ``FAMILY_DRAWS`` times (so a seed always gives the same scenario); the name says the seed."""
    import numpy as np

    from proxplan.fileio import UserError
    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.checks.precheck import check_starts_and_goals
    from proxplan.planner.errors import InfeasibleError

    if n_vehicles < 1:
        raise ValueError(f"a layout needs at least one vehicle, got {n_vehicles}")
    rng = np.random.default_rng(seed)
    for draw in range(FAMILY_DRAWS):
        doc = _family_draw(n_vehicles, rng, seed)
        try:
            check_starts_and_goals(scenario_from_dict(doc, label=doc["name"]), mode="downwash")
        except (UserError, InfeasibleError):
            continue
        doc["description"] = (
            f"random formation change, seed {seed}, draw {draw + 1} (earlier draws broke the pre-checks)"
        )
        return doc
    raise ValueError(f"random formation seed {seed}: no valid draw in {FAMILY_DRAWS}")


def _family_draw(n: int, rng, seed: int) -> dict[str, Any]:
    import numpy as np

    all_types = list(DEFAULT_TYPES) + ["large-quad"]
    k = int(rng.integers(1, len(all_types) + 1))
    mix = list(rng.choice(all_types, size=k, replace=False))
    share = rng.dirichlet(np.ones(k))
    types = [str(mix[int(rng.choice(k, p=share))]) for _ in range(n)]

    def region() -> np.ndarray:
        pitch = float(rng.uniform(*FAMILY_PITCH_M))
        layers = int(rng.choice(FAMILY_LAYERS))
        gap = float(rng.uniform(*FAMILY_LAYER_GAP_M))
        per = math.ceil(n / layers)
        cols = math.ceil(math.sqrt(per))
        rows = math.ceil(per / cols)
        pts = []
        for i in range(n):
            layer, j = i % layers, i // layers
            r, c = divmod(j, cols)
            stagger = 0.5 * pitch * (layer % 2)
            pts.append(
                [(c - 0.5 * (cols - 1)) * pitch + stagger, (r - 0.5 * (rows - 1)) * pitch + stagger, layer * gap]
            )
        a = float(rng.uniform(0.0, 2.0 * math.pi))
        rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
        return np.array(pts) @ rot.T

    starts, goals = region(), region()
    half = lambda p: float(np.abs(p[:, :2]).max())  # noqa: E731 - half width of a region, m
    gap = float(rng.uniform(*FAMILY_REGION_GAP_M))
    direction = float(rng.uniform(0.0, 2.0 * math.pi))
    offset = (half(starts) + half(goals) + gap) * np.array([math.cos(direction), math.sin(direction)])
    goals[:, :2] += offset
    z0 = float(LOW_Z_M)
    starts[:, 2] += z0
    goals[:, 2] += z0
    perm = rng.permutation(n)
    lo = np.minimum(starts.min(axis=0), goals.min(axis=0))[:2] - 1.2
    hi = np.maximum(starts.max(axis=0), goals.max(axis=0))[:2] + 1.2
    top = float(max(starts[:, 2].max(), goals[:, 2].max())) + 1.5
    obstacles = []
    for i in range(int(rng.integers(FAMILY_OBSTACLES[0], FAMILY_OBSTACLES[1] + 1))):
        centre = 0.5 * offset + rng.uniform(-0.5, 0.5, 2) * max(gap, 0.6)  # between the regions
        size = rng.uniform(0.2, 0.6, 2)
        obstacles.append(
            {
                "name": f"box-{i}",
                "min": [round(float(centre[0] - size[0] / 2), 4), round(float(centre[1] - size[1] / 2), 4), 0.0],
                "max": [
                    round(float(centre[0] + size[0] / 2), 4),
                    round(float(centre[1] + size[1] / 2), 4),
                    round(top, 4),
                ],
            }
        )
    vehicles = {
        f"v{i:03d}": {
            "type": types[i],
            "start": [round(float(x), 4) for x in starts[i]],
            "goal": [round(float(x), 4) for x in goals[int(perm[i])]],
        }
        for i in range(n)
    }

    # drop boxes that would hold a start or a goal (with a body's margin)
    def inside(b, p, m=0.5):
        return all(b["min"][d] - m <= p[d] <= b["max"][d] + m for d in range(2))

    obstacles = [
        b for b in obstacles if not any(inside(b, v["start"]) or inside(b, v["goal"]) for v in vehicles.values())
    ]
    return {
        "name": f"random-{n}-seed{seed}",
        "workspace": {
            "min": [round(float(lo[0]), 4), round(float(lo[1]), 4), 0.0],
            "max": [round(float(hi[0]), 4), round(float(hi[1]), 4), round(top, 4)],
        },
        "obstacles": obstacles,
        "limits": _limits_block(0.1, 0.25),
        "vehicles": vehicles,
    }


LAYOUTS: dict[str, Callable[..., dict[str, Any]]] = {
    "pillar": formation_change,
    "grid": grid_reshuffle,
    "circle": circle_swap,
    "corridor": corridor,
}


def layout_doc(layout: str, n_vehicles: int, *, assign: str = "fixed") -> dict[str, Any]:
    """The scenario mapping of the named layout (:data:`LAYOUTS`) with ``n_vehicles``, its goals fixed or, with
    ``assign="by_type"``, assigned within each vehicle type (the scenario's ``assign_goals``)."""
    doc = LAYOUTS[layout](n_vehicles)
    if assign == "by_type":
        doc["assign_goals"] = "by_type"
    return doc


def main(argv: list[str] | None = None) -> int:
    import yaml

    from proxplan.fileio import UserError, atomic_write_text, check_output_file
    from proxplan.planfile import MAX_VEHICLES

    parser = argparse.ArgumentParser(
        prog="python -m proxplan.planner.formations",
        description="Write a formation-change scenario of N vehicles (two staggered layers, a pillar).",
    )
    parser.add_argument("n", type=int, metavar="N", help="number of vehicles (>= 1)")
    parser.add_argument("--out", required=True, metavar="FILE.yaml", help="scenario file to write")
    parser.add_argument("--spacing", type=float, default=0.6, help="slot spacing within a layer, m (default 0.6)")
    parser.add_argument("--authority-fraction", type=float, default=0.1, help="limits.authority_fraction (default 0.1)")
    args = parser.parse_args(argv)
    try:
        if not 1 <= args.n <= MAX_VEHICLES:
            raise UserError(
                f"N: expected a whole number from 1 to {MAX_VEHICLES} (the planner's swarm limit), got {args.n}"
            )
        if not args.spacing > 0:
            raise UserError(f"--spacing: expected a positive number of metres, got {args.spacing}")
        path = check_output_file(args.out)
        doc = formation_change(args.n, spacing_m=args.spacing, authority_fraction=args.authority_fraction)
        header = (
            f"# Formation change of {args.n} vehicles: two staggered layers 0.5 m apart west of a pillar, each vehicle\n"
            "# flies to the other layer on the east side (generated by python -m proxplan.planner.formations).\n"
        )
        atomic_write_text(path, header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    except UserError as err:
        print(f"python -m proxplan.planner.formations: error: {err}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
