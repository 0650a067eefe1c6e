"""``proxplan schema scenario|vehicles|model|manifest|plan|truth [--out FILE] [--json]``.

The JSON Schema of a user file format, generated from its declared model (:mod:`proxplan.schemas`).
Module level imports only the standard library and the format names (fast ``proxplan --help``).
"""

from __future__ import annotations

import argparse
import json

from proxplan.schemas import FORMATS


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "schema",
        help="JSON Schema of a file format (for editor completion and checks)",
        description=(
            "The JSON Schema (draft 7) of a user file format: every key with its form, unit, default and "
            "description. Without --json, a table of the keys; --json prints the schema itself; --out writes it to "
            "a file. Editors with yaml-language-server (VS Code's YAML extension, ...) use it through a first line "
            "'# yaml-language-server: $schema=PATH' in the YAML file (docs/file_formats.md). Formats: "
            + "; ".join(f"{name}: {used}" for name, (_, used) in FORMATS.items())
        ),
    )
    p.add_argument("format", choices=tuple(FORMATS), help="file format")
    p.add_argument("--out", metavar="FILE.json", help="also write the schema to this file")
    p.add_argument("--json", action="store_true", help="print the schema (one JSON object) on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from proxplan.fileio import atomic_write_text, check_output_file
    from proxplan.schemas import describe, schema_text

    text = schema_text(args.format)
    if args.out:
        atomic_write_text(check_output_file(args.out), text)
    if args.json:
        print(json.dumps(json.loads(text)))
        return 0
    if args.out:
        print(f"wrote {args.out}")
        return 0
    rows = describe(args.format)
    width = min(max(len(key) for key, _, _ in rows), 40)
    for key, form, about in rows:
        print(f"{key:{width}s}  {form}" + (f"\n{'':{width}s}    {about}" if about else ""))
    return 0
