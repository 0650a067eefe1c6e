"""`proxplan costmap`: cutoff map r_cut(dz) + 3-D wrench table of a vehicle pair (DESIGN.md s. 4).

    proxplan costmap --source small-quad --target large-quad --out maps/sl.npz [--json]
    proxplan costmap --all --out-dir costmaps/data        # every ordered pair of built-in types

Writes PATH (.npz, see :mod:`proxplan.costmaps.map_store`) and a PNG beside it (same stem); ``--json`` prints
one JSON object on stdout; progress goes to stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

from proxplan.cli_args import add_model_argument, load_model_argument

_RULES = ("conservative", "model", "forbid")
_DEFAULT_LEVELS = ("0.02", "0.05", "0.1", "0.25", "0.5")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "costmap",
        help="cutoff map r_cut(dz) and 3-D wrench table of a source/target pair",
        description=(
            "For a hovering SOURCE and a TARGET below it, compute the horizontal separation r_cut "
            "beyond which the target's authority usage stays below each threshold level, for every "
            "vertical separation dz (m, target below), plus the 3-D wrench table (x, y, dz) with a "
            "smooth interpolant. Writes OUT (.npz) and a PNG beside it. With --all, every ordered pair "
            "of built-in types into --out-dir (this regenerates the shipped maps with "
            "--out-dir costmaps/data)."
        ),
    )
    p.add_argument("--source", metavar="TYPE", help="vehicle type producing the downwash (above)")
    p.add_argument("--target", metavar="TYPE", help="vehicle type receiving it (below)")
    p.add_argument("--out", metavar="PATH.npz", help="output map file (a PNG of the same stem is written beside it)")
    p.add_argument(
        "--all", action="store_true", help="every ordered pair of built-in vehicle types (and those of --vehicle-file)"
    )
    p.add_argument("--out-dir", metavar="DIR", help="with --all: directory for SOURCE__TARGET.npz files")
    p.add_argument(
        "--levels", nargs="+", default=list(_DEFAULT_LEVELS), metavar="U",
        help="authority-usage thresholds to store, each in [0.01, 10] (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--default-level",
        default="0.5",
        metavar="U",
        help="level of the r_cut_m array (default 0.5 = DESIGN's authority_fraction)",
    )
    p.add_argument(
        "--invalid-rule",
        default="conservative",
        choices=_RULES,
        help="cutoff where dz <= 3 L_source (model not valid): conservative (default), "
        "model (extrapolated numbers) or forbid (whole cylinder)",
    )
    p.add_argument(
        "--field-form",
        choices=("inverse-z", "printed"),
        default=None,
        help="form of (S0-1); default: the --model / vehicle file's model.field_form or inverse-z",
    )
    p.add_argument("--vehicle-file", metavar="FILE.yaml", help="custom vehicle types")
    add_model_argument(
        p, "its vehicles override same-named types, its field form and effects between vehicles enter the maps"
    )
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run_costmap)


def _level(text: str, flag: str) -> float:
    from proxplan.fileio import UserError

    try:
        value = float(text)
    except ValueError:
        raise UserError(f"{flag}: expected a number (authority usage, e.g. 0.05), got {text!r}") from None
    if not (math.isfinite(value) and 0.01 <= value <= 10.0):
        raise UserError(f"{flag}: expected an authority usage in [0.01, 10], got {text!r}")
    return value


def _pairs(args: argparse.Namespace, custom: dict) -> list[tuple]:
    from proxplan.fileio import UserError
    from proxplan.physics import BUILTIN_VEHICLES, resolve_vehicle

    if args.all:
        if args.source or args.target or args.out:
            raise UserError("--all builds every pair: give --out-dir DIR, not --source/--target/--out")
        if not args.out_dir:
            raise UserError("--all needs --out-dir DIR (e.g. --out-dir costmaps/data)")
        vehicles = {**BUILTIN_VEHICLES, **custom}  # custom types of --vehicle-file too
        return [(vehicles[s], vehicles[t]) for s in vehicles for t in vehicles]
    missing = [
        flag for flag, value in (("--source", args.source), ("--target", args.target), ("--out", args.out)) if not value
    ]
    if missing:
        raise UserError(f"missing {', '.join(missing)} (or use --all --out-dir DIR)")
    if args.out_dir:
        raise UserError("--out-dir goes with --all; for one pair use --out PATH.npz")
    if not args.out.endswith(".npz"):
        raise UserError(f"--out: expected a path ending in .npz, got {args.out!r}")
    return [
        (resolve_vehicle(args.source, custom, where="--source"), resolve_vehicle(args.target, custom, where="--target"))
    ]


def run_costmap(args: argparse.Namespace) -> int:
    from pathlib import Path

    from tqdm import tqdm

    from proxplan.costmaps import build_pair_maps, save_pair_maps
    from proxplan.fileio import check_output_file, output_folder
    from proxplan.physics import ModelOptions

    start = time.perf_counter()
    custom, model = {}, {}
    if args.vehicle_file:
        from proxplan.physics import load_model_section, load_vehicle_file

        custom = load_vehicle_file(args.vehicle_file)
        model = load_model_section(args.vehicle_file)
        from proxplan.physics import vehicle_file_notes

        for note in vehicle_file_notes(args.vehicle_file):
            print(f"proxplan costmap: note: {note}", file=sys.stderr)
    levels = tuple(_level(v, "--levels") for v in args.levels)
    default_level = _level(args.default_level, "--default-level")
    calibrated = load_model_argument(args, "costmap")
    effects: tuple = ()
    if calibrated is not None:
        from proxplan.costmaps import unmapped_effect_names
        from proxplan.physics import target_only_notes

        custom = {**custom, **calibrated.vehicles}
        model = {"field_form": calibrated.options.field_form}
        effects = calibrated.between_vehicle_effects
        for note in target_only_notes(calibrated, args.model):
            print(f"proxplan costmap: note: {note}", file=sys.stderr)
        for name in unmapped_effect_names(effects):
            print(
                f"proxplan costmap: note: {args.model}: {name} is not applied by cost maps (azimuth-dependent)",
                file=sys.stderr,
            )
    field_form = args.field_form or model.get("field_form") or "inverse-z"
    options = ModelOptions(field_form=field_form)
    pairs = _pairs(args, custom)
    if args.all:
        folder, flag = Path(args.out_dir), "--out-dir"
    else:
        folder, flag = check_output_file(args.out).parent, "--out"
    results = []
    with output_folder(folder, flag=flag) as stage:  # every map and plot lands together, or none
        bar = tqdm(pairs, desc="costmap", unit="pair", file=sys.stderr, disable=len(pairs) < 2)
        for source, target in bar:
            bar.set_postfix_str(f"{source.name} -> {target.name}")
            maps = build_pair_maps(
                source, target, options=options, levels=levels, default_level=default_level,
                invalid_rule=args.invalid_rule, effects=effects,
            )  # fmt: skip
            name = Path(args.out).name if not args.all else f"{source.name}__{target.name}.npz"
            save_pair_maps(maps, stage / name)
            png = None
            if not args.no_plot:
                from proxplan.costmaps import plot_cutoff

                plot_cutoff(maps.cutoff, (stage / name).with_suffix(".png"))
                png = (folder / name).with_suffix(".png")
            results.append(_summary(maps, folder / name, png))
    elapsed = time.perf_counter() - start
    if args.json:
        doc = results[0] if len(results) == 1 else {"maps": results}
        doc["elapsed_s"] = elapsed
        print(json.dumps(doc))
        return 0
    for r in results:
        print(f"{r['source']} -> {r['target']}: {r['out']}" + (f" (+ {r['plot']})" if r["plot"] else ""))
        print(
            f"  peak usage in the valid zone {r['peak_usage_valid_zone']:.3f}; max r_cut per level: "
            + ", ".join(f"{lv:g}: {rc:.2f} m" for lv, rc in zip(r["levels"], r["max_r_cut_valid_m"]))
        )
    print(f"{len(results)} map(s) in {elapsed:.1f} s", file=sys.stderr)
    return 0


def _summary(maps, out, png) -> dict:
    c = maps.cutoff
    valid_rows = c.r_cut_levels_m[:, c.valid] if c.valid.any() else c.r_cut_levels_m[:, :0]
    return {
        "source": c.source_name,
        "target": c.target_name,
        "out": str(out),
        "plot": str(png) if png else None,
        "param_hash": maps.metadata["param_hash"],
        "field_form": maps.metadata["model"]["field_form"],
        "effects": maps.metadata["model"]["effects"],
        "invalid_rule": c.invalid_rule,
        "validity_dz_m": c.validity_dz_m,
        "levels": [float(v) for v in c.levels],
        "default_level": c.default_level,
        "dz_m": [round(float(v), 5) for v in c.dz_m],
        "r_cut_m": [round(float(v), 5) for v in c.default_r_cut_m],
        "max_r_cut_valid_m": [float(row.max()) if row.size else 0.0 for row in valid_rows],
        "peak_usage_valid_zone": maps.metadata["peak_usage_valid_zone"],
        "table_peak_abs_force_N": maps.table.peak_abs_force_N,
    }
