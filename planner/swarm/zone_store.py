"""Shipped undamped-zone tables (:func:`proxplan.planner.swarm.keepout.undamped_radius_m`), keyed on
everything a table depends on, so that a ``proxplan plan`` process does not search them again
(issue 37, round 19A: the search took 3.3-4.5 s of CPU per process for three types).

A table is looked up by the SHA-256 (:func:`facts_key`) of a JSON document of its *facts*, built by
the caller: both vehicles' full parameters (controller, motor, drag, ...), the model options, the
effects, the authority level and invalid-zone rule, the search's constants, the cut-off tables that
bound the search (so the cost maps it reads), the source text of every module the search runs
(:func:`code_digest`: the whole physics package, the cost maps' wrench, the search function) and the
NumPy version (its LAPACK computes the poles). Any change of any of them gives another key: the
table is then searched again (never a stale one), and ``tests/planner/test_swarm_zone_store.py``
says to ship it again (:func:`proxplan.planner.swarm.keepout.ship_undamped_zones`;
``python -m proxplan.planner.swarm.keepout``).

File: :data:`ZONES_PATH`, JSON ``{"format": FORMAT, "zones": {key: {"source", "target", "level",
"radius_m": [...]}}}``; floats written by ``json`` round-trip exactly.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path

import numpy as np

from proxplan.costmaps import DATA_DIR

FORMAT = 1
"""Bump when the file's layout or the meaning of a stored table changes."""
ZONES_PATH = DATA_DIR / "undamped_zones.json"
"""The shipped tables, beside the shipped cost maps (packaged as ``proxplan.costmaps`` data)."""


def facts_key(facts: dict) -> str:
    """SHA-256 (hex) of the canonical JSON of ``facts`` (with :data:`FORMAT`)."""
    text = json.dumps({"format": FORMAT, **facts}, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


@lru_cache(maxsize=8)
def code_digest(*texts: str) -> str:
    """SHA-256 (hex) of the physics package's source files (every ``*.py`` of
    :mod:`proxplan.physics`, in name order), the cost maps' wrench (:mod:`proxplan.costmaps.effects`)
    and the extra source ``texts`` (the search function's own)."""
    import proxplan.costmaps.effects as wrench
    import proxplan.physics as physics

    h = hashlib.sha256()
    files = sorted(Path(physics.__file__).resolve().parent.glob("*.py")) + [Path(wrench.__file__).resolve()]
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    for t in texts:
        h.update(t.encode())
    return h.hexdigest()


@lru_cache(maxsize=4)
def _shipped(path: str) -> dict:
    p = Path(path)
    if not p.is_file():
        return {}
    doc = json.loads(p.read_text())
    return doc.get("zones", {}) if doc.get("format") == FORMAT else {}


def shipped_zone(key: str, path: Path = ZONES_PATH) -> np.ndarray | None:
    """The shipped table (K,) of ``key`` (m), or None."""
    entry = _shipped(str(path)).get(key)
    return None if entry is None else np.asarray(entry["radius_m"], dtype=float)


def write_zones(entries: dict[str, dict], path: Path = ZONES_PATH) -> Path:
    """Write ``entries`` (key -> {"source", "target", "level", "radius_m"}) as the shipped file."""
    rows = [f"  {json.dumps(k)}: {json.dumps(entries[k], separators=(',', ':'))}" for k in sorted(entries)]
    path.write_text(f'{{"format": {FORMAT}, "zones": {{\n' + ",\n".join(rows) + "\n}}\n")
    _shipped.cache_clear()
    return path
