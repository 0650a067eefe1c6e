"""One import namespace: everything installs under ``proxplan.*`` and nothing else at top level.

The repository keeps one folder per stage (``physics/``, ``planner/``, ...); pyproject.toml's
``[tool.setuptools.package-dir]`` maps each into the namespace. The fast tests check the mapping
and that no file imports a stage by its bare folder name (which would only work by accident, from
the repository root). The slow test builds the wheel, installs it in a fresh virtualenv next to
PyPI's ``identify`` (one of the names the old layout clashed with) and runs the product from
outside the repository.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest
import tomllib

from tests.conftest import REPO, SCENARIOS, SHARED

with open(REPO / "pyproject.toml", "rb") as _fh:
    SETUPTOOLS = tomllib.load(_fh)["tool"]["setuptools"]
PACKAGE_DIR: dict[str, str] = SETUPTOOLS["package-dir"]
STAGES = sorted(folder for package, folder in PACKAGE_DIR.items() if package != "proxplan")


def _folder(package: str) -> Path:
    """The repository folder of a dotted package: mapped directly or inside its nearest mapped parent."""
    parent = package
    while parent not in PACKAGE_DIR:
        parent = parent.rpartition(".")[0]
        assert parent, f"{package} has no package-dir entry"
    return REPO / PACKAGE_DIR[parent] / Path(*package[len(parent) :].split(".")[1:])


def test_every_package_is_under_the_namespace_and_mapped():
    packages = SETUPTOOLS["packages"]
    assert all(p == "proxplan" or p.startswith("proxplan.") for p in packages)
    for package in packages:
        folder = _folder(package)
        assert (folder / "__init__.py").is_file(), f"{package} -> {folder}: no __init__.py"


def test_every_python_package_folder_is_installed():
    """A new package folder with an __init__.py must be listed, or the wheel silently lacks it
    (sub-packages of a stage, e.g. planner/swarm/, included)."""
    installed = {_folder(p) for p in SETUPTOOLS["packages"]}
    for folder in [*STAGES, PACKAGE_DIR["proxplan"]]:
        for init in (REPO / folder).rglob("__init__.py"):
            assert init.parent in installed, f"{init.parent.relative_to(REPO)} is not in pyproject's packages"


def _bare_stage_imports(path: Path, root: Path = REPO) -> list[str]:
    stages = set(STAGES)
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names = [node.module]
        found += [f"{path.relative_to(root)}:{node.lineno}: {n}" for n in names if n.split(".")[0] in stages]
    return found


def test_no_file_imports_a_stage_by_its_folder_name():
    files = [p for p in REPO.rglob("*.py") if not {".git", "build", ".venv"} & set(p.relative_to(REPO).parts)]
    bare = [hit for path in files for hit in _bare_stage_imports(path)]
    assert not bare, "imports outside the proxplan namespace:\n" + "\n".join(bare)


def test_the_bare_import_check_finds_one(tmp_path):
    planted = tmp_path / "planted.py"
    planted.write_text("import physics.vehicles\nfrom planner import plan\nfrom proxplan.planner import plan\n")
    assert len(_bare_stage_imports(planted, tmp_path)) == 2


def _run(cmd: list[str], cwd: Path, timeout: float = 900) -> subprocess.CompletedProcess:
    res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, f"{' '.join(map(str, cmd))}\n{res.stdout[-2000:]}\n{res.stderr[-2000:]}"
    return res


@pytest.mark.slow
def test_wheel_installs_next_to_pypi_identify_and_runs_outside_the_repo(tmp_path):
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(REPO)], cwd=tmp_path)
    (wheel,) = dist.glob("proxplan-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names} == {"proxplan", wheel.name.split("-py3")[0] + ".dist-info"}
    assert any(n.startswith("proxplan/costmaps/data/") and n.endswith(".npz") for n in names)

    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)  # no system site-packages: only what the wheel declares
    py = env_dir / "bin" / "python"
    _run([str(py), "-m", "pip", "install", "-q", str(wheel), "identify"], cwd=tmp_path)
    work = tmp_path / "elsewhere"
    work.mkdir()
    # PyPI's identify keeps working and ours lives under the namespace (the one-liner,
    # `import identify; identify.identify...`, fails even without proxplan: identify/__init__.py is
    # empty, so the submodule must be imported)
    res = _run([str(py), "-c", "import identify.identify as i; print(sorted(i.tags_from_filename('a.py')))"], work)
    assert "python" in res.stdout
    _run([str(py), "-c", "from proxplan.identify import IdentifyOptions; import proxplan.physics"], work)
    for bare in STAGES:
        if bare == "identify":
            continue
        res = subprocess.run([str(py), "-c", f"import {bare}"], cwd=work, capture_output=True, text=True)
        assert res.returncode != 0, f"'{bare}' is importable at top level"

    proxplan = env_dir / "bin" / "proxplan"
    res = _run([str(proxplan), "plan", str(SCENARIOS / "battery_swap.yaml"), "--out", str(work / "bs"), "--json"], work)
    assert '"feasible": true' in res.stdout
    _run([str(proxplan), "verify", str(work / "bs" / "plan.json")], work)
    if not (SHARED / "data" / "neural-swarm").is_dir():
        pytest.skip("../shared/data/neural-swarm not present")
    res = _run([str(proxplan), "identify", str(REPO / "manifests" / "neural-swarm.yaml"), "--out", str(work / "id"), "--json"], work)  # fmt: skip
    assert (work / "id" / "report.md").is_file()
