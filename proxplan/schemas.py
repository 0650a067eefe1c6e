"""JSON Schemas of every user file format, generated from the declared models.

``schemas/<format>.json`` in the repository are :func:`write_schemas`'s output (``python
scripts/write_schemas.py``; a test fails when one is stale); shipped YAML files name theirs on their
first line (``# yaml-language-server: $schema=../schemas/scenario.json``), so VS Code (the YAML
extension) and any editor with yaml-language-server complete keys, show each key's description and
unit, and underline mistakes as the user types. ``proxplan schema FORMAT`` prints one.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

FORMATS = {
    "scenario": ("proxplan scenario file", "proxplan plan / view SCENARIO.yaml (docs/planfile.md)"),
    "vehicles": ("proxplan vehicle file", "custom vehicle types: vehicle_file: in a scenario, --vehicle-file"),
    "model": ("proxplan calibrated model file", "proxplan identify --save-model; --model FILE or model_file:"),
    "manifest": ("proxplan flight-log manifest", "proxplan identify / evaluate MANIFEST.yaml"),
    "plan": ("proxplan plan.json", "written by proxplan plan; read by verify, simulate, view, export, certify"),
    "truth": ("proxplan truth file", "proxplan simulate --truth FILE.yaml: the simulated world beyond the model"),
}
"""Format name -> (title, where it is used)."""
SCHEMA_FOLDER = "schemas"
"""Where the repository keeps the generated schemas (relative to its root)."""


def _model(name: str) -> Any:
    if name == "scenario":
        from proxplan.planfile import ScenarioFile

        return ScenarioFile
    if name == "plan":
        from proxplan.planfile import PlanFile

        return PlanFile
    if name == "manifest":
        from proxplan.identify import ManifestFile

        return ManifestFile
    from proxplan.physics import ModelFile, TruthFile, VehicleFile

    return {"vehicles": VehicleFile, "model": ModelFile, "truth": TruthFile}[name]


def schema(name: str) -> dict[str, Any]:
    """The JSON Schema (draft 7) of format ``name`` (a key of :data:`FORMATS`)."""
    from proxplan.fileio import json_schema

    title, used = FORMATS[name]
    model = _model(name)
    return json_schema(model, title=title, description=f"{(model.__doc__ or '').strip()} Used by: {used}.")


def schema_text(name: str) -> str:
    """The schema of ``name`` as the repository keeps it (2-space JSON, newline at the end)."""
    return json.dumps(schema(name), indent=2) + "\n"


def write_schemas(folder: str | Path) -> list[Path]:
    """Write ``<folder>/<format>.json`` for every format (atomically); returns the paths."""
    from proxplan.fileio import atomic_write_text

    return [atomic_write_text(Path(folder) / f"{name}.json", schema_text(name)) for name in FORMATS]


def describe(name: str) -> list[tuple[str, str, str]]:
    """(key path, expected form, description) of every key of format ``name``, in file order:
    the terminal view of the schema (``proxplan schema FORMAT``)."""
    from proxplan.fileio import schema_rows

    return schema_rows(schema(name))
