"""Reading user-written files (YAML, JSON) with one-line errors that name the file.

Every loader of user input (vehicles, scenarios, truth files, manifests, plans) reads through
these helpers, so a missing file or a syntax error reads the same everywhere.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from costmaps.errors import UserError


def read_text(path: str | Path, *, what: str) -> str:
    """The file's text; UserError ``"<path>: cannot read <what> (<reason>)"`` otherwise."""
    try:
        return Path(path).read_text()
    except OSError as err:
        raise UserError(f"{path}: cannot read {what} ({err.strerror or err})") from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: cannot read {what} (not a text file)") from None


def read_yaml(path: str | Path, *, what: str) -> Any:
    """The parsed YAML document (None for an empty file); UserError on unreadable or bad YAML."""
    import yaml

    text = read_text(path, what=what)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise UserError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None


def read_json(path: str | Path, *, what: str) -> Any:
    """The parsed JSON document; UserError on unreadable or bad JSON."""
    text = read_text(path, what=what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise UserError(f"{path}: not valid JSON ({err.msg} at line {err.lineno})") from None
