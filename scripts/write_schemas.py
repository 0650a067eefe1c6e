"""Write the JSON Schema of every user file format to ``schemas/<format>.json`` from the declared
models (:mod:`proxplan.schemas`). Run after changing a format; ``tests/cli/test_schemas.py`` fails
while a file here is stale.

    python scripts/write_schemas.py
"""

from __future__ import annotations

from pathlib import Path

from proxplan.schemas import SCHEMA_FOLDER, write_schemas

if __name__ == "__main__":
    for path in write_schemas(Path(__file__).resolve().parents[1] / SCHEMA_FOLDER):
        print(f"wrote {path}")
