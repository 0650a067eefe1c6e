"""Type-check the installed namespace (``proxplan.*``) with mypy, from the source folders.

The repository keeps one top-level folder per stage (``physics/``, ``planner/``, ...) and
``pyproject.toml``'s ``[tool.setuptools.package-dir]`` maps each into the ``proxplan`` namespace.
setuptools' editable install resolves that mapping with an import hook, which mypy cannot follow
(it looks for ``proxplan/physics/*.py`` on disk and would silently treat every
``proxplan.physics`` import as missing). So this script builds ``build/typecheck/proxplan``, a
tree of symbolic links with the installed shape, taken from the same ``package-dir`` table (one
source of truth), runs mypy on it with the ``[tool.mypy]`` options, and prints mypy's report with
the repository's own paths. Exit code: mypy's.

Usage: ``python scripts/typecheck.py [extra mypy arguments]``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import tomllib

REPO = Path(__file__).resolve().parents[1]
VIEW = REPO / "build" / "typecheck"
NAMESPACE = "proxplan"


def package_dirs() -> dict[str, str]:
    """``{dotted package: repository folder}`` from pyproject.toml's package-dir table."""
    with open(REPO / "pyproject.toml", "rb") as fh:
        config = tomllib.load(fh)
    return dict(config["tool"]["setuptools"]["package-dir"])


def build_view() -> Path:
    """Link tree ``build/typecheck/proxplan`` with the installed layout; returns its root."""
    if VIEW.exists():
        shutil.rmtree(VIEW)
    root = VIEW / NAMESPACE
    root.mkdir(parents=True)
    mapping = package_dirs()
    for entry in sorted((REPO / mapping[NAMESPACE]).iterdir()):  # the CLI package's own files
        if entry.name != "__pycache__":
            (root / entry.name).symlink_to(entry)
    for package, folder in mapping.items():
        if package != NAMESPACE:
            (root / package.split(".", 1)[1]).symlink_to(REPO / folder, target_is_directory=True)
    return root


def main(argv: list[str]) -> int:
    root = build_view()
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", str(root.relative_to(REPO)), *argv], cwd=REPO, capture_output=True, text=True
    )
    mapping = package_dirs()
    out = proc.stdout + proc.stderr
    for package, folder in sorted(mapping.items(), key=lambda kv: -len(kv[0])):
        view_path = f"{VIEW.relative_to(REPO)}/{package.replace('.', '/')}/"
        out = out.replace(view_path, f"{folder}/")
    sys.stdout.write(out)
    return proc.returncode


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
