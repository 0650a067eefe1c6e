"""Reading user files with one-line errors, and writing output files atomically.

Every loader of user input (vehicles, scenarios, truth files, manifests, plans) reads through
these helpers, so a missing file or a syntax error reads the same everywhere; every writer of
results goes through a temporary file and a rename, so nothing is left half-written on failure.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from proxplan.fileio.errors import UserError


def read_text(path: str | Path, *, what: str) -> str:
    """The file's text; UserError ``"<path>: cannot read <what> (<reason>)"`` otherwise."""
    try:
        return Path(path).read_text()
    except OSError as err:
        raise UserError(f"{path}: cannot read {what} ({err.strerror or err})") from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: cannot read {what} (not a text file)") from None


def _duplicate_key(node: Any, path: str = "") -> tuple[str, int, int] | None:
    """(dotted key path, first line, second line) of the first key given twice in one mapping of a
    composed YAML node tree, or None."""
    import yaml

    if isinstance(node, yaml.MappingNode):
        seen: dict[Any, int] = {}
        for key_node, value_node in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = key_node.value if isinstance(key_node, yaml.ScalarNode) else str(key_node.start_mark)
            dotted = f"{path}.{key}" if path else str(key)
            line = key_node.start_mark.line + 1
            if key in seen:
                return dotted, seen[key], line
            seen[key] = line
            found = _duplicate_key(value_node, dotted)
            if found:
                return found
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            found = _duplicate_key(item, f"{path}[{i}]")
            if found:
                return found
    return None


def parse_yaml(text: str, *, label: str) -> Any:
    """Parse YAML ``text`` (None for an empty document); UserError naming ``label`` on bad YAML
    or on a key given twice in one mapping (PyYAML would silently keep the last)."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)(text)  # libyaml parses swarm files fast
    try:
        node = loader.get_single_node()  # parsed once: checked for duplicates, then constructed
        duplicate = _duplicate_key(node)
        if duplicate:
            key, first, again = duplicate
            raise UserError(f"{label}: {key}: duplicate key (lines {first} and {again}); expected each key once")
        return None if node is None else loader.construct_document(node)
    except yaml.YAMLError as err:
        raise UserError(f"{label}: not valid YAML ({str(err).splitlines()[0]})") from None
    finally:
        loader.dispose()


def read_yaml(path: str | Path, *, what: str) -> Any:
    """The parsed YAML document (None for an empty file); UserError on unreadable or bad YAML,
    and on a key given twice in one mapping."""
    return parse_yaml(read_text(path, what=what), label=str(path))


def read_json(path: str | Path, *, what: str) -> Any:
    """The parsed JSON document; UserError on unreadable or bad JSON."""
    text = read_text(path, what=what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise UserError(f"{path}: not valid JSON ({err.msg} at line {err.lineno})") from None


@contextmanager
def atomic_output(path: str | Path, *, suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed onto ``path`` on success, removed
    on failure, so a failed run never leaves a half-written file. Creates the parent folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + rename); returns the path."""
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (temporary file + rename); returns the path."""
    return atomic_write_bytes(path, text.encode())


def save_figure(fig: Any, path: str | Path, **savefig_kwargs: Any) -> Path:
    """Save a matplotlib figure as PNG atomically and close it; returns the path."""
    import matplotlib.pyplot as plt

    try:
        with atomic_output(path, suffix=".png") as tmp:
            fig.savefig(tmp, format="png", **savefig_kwargs)
    finally:
        plt.close(fig)
    return Path(path)


def _unwritable(path: Path, flag: str, err: OSError, *, what: str = "folder") -> UserError:
    reason = err.strerror or str(err)
    return UserError(f"{flag} {path}: cannot write there ({reason}); expected a writable {what} path")


def check_output_file(path: str | Path, *, flag: str = "--out") -> Path:
    """``path`` as an output file: its folder is created and must be writable, and ``path`` must
    not be a folder; UserError naming ``flag`` otherwise (checked before any long computation)."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{flag} {path}: is a folder; expected a file path")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=path.parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise _unwritable(path, flag, err, what="file") from None
    return path


@contextmanager
def output_folder(path: str | Path, *, flag: str = "--out") -> Iterator[Path]:
    """Stage a command's outputs: yields an empty temporary folder beside ``path``; when the block
    succeeds, every file in it moves into ``path`` (created when there is a file to move; files of the
    same name are replaced, others kept); when it fails, the stage is removed and ``path`` is untouched. Enter it before the
    long computation: an existing file at ``path`` or an unwritable location is a UserError naming
    ``flag`` at once."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserError(f"{flag} {path}: exists and is not a folder; expected a folder path")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent))
    except OSError as err:
        raise _unwritable(path, flag, err) from None
    try:
        yield stage
        try:
            for item in sorted(stage.rglob("*")):
                if item.is_file():
                    target = path / item.relative_to(stage)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(item, target)
        except OSError as err:
            raise _unwritable(path, flag, err) from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)
