"""The published JSON Schemas (schemas/*.json): generated from the declared models, up to date, named
by every shipped YAML file, and agreeing with the loaders on good and mistyped files."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import jsonschema
import pytest
import yaml

from proxplan.fileio import UserError
from proxplan.schemas import FORMATS, SCHEMA_FOLDER, schema_text
from tests.conftest import REPO

SCHEMAS = REPO / SCHEMA_FOLDER
SCHEMA_LINE = re.compile(r"^# yaml-language-server: \$schema=(\S+)\n")
SHIPPED = {
    "scenario": sorted((REPO / "scenarios").glob("*.yaml")),
    "manifest": sorted((REPO / "manifests").glob("*.yaml")),
    "truth": sorted((REPO / "examples" / "truth").glob("*.yaml")),
    "model": sorted((REPO / "examples" / "models").glob("*.yaml")),
}


def _validator(name: str) -> jsonschema.Draft7Validator:
    schema = json.loads((SCHEMAS / f"{name}.json").read_text())
    jsonschema.Draft7Validator.check_schema(schema)
    return jsonschema.Draft7Validator(schema)


def _load(name: str, path: Path) -> None:
    """Read ``path`` with the proxplan loader of format ``name`` (UserError on a mistake)."""
    if name == "scenario":
        from proxplan.planfile import load_scenario

        load_scenario(path)
    elif name == "model":
        from proxplan.physics import load_model_file

        load_model_file(path)
    elif name == "vehicles":
        from proxplan.physics import load_vehicle_file

        load_vehicle_file(path)
    elif name == "truth":
        from proxplan.flightsim.truth import load_truth_file

        load_truth_file(path)
    elif name == "manifest":  # the declared form only: the logs it names live outside the repository
        from proxplan.fileio import read_yaml, validate
        from proxplan.identify import ManifestFile

        validate(ManifestFile, read_yaml(path, what="manifest"), label=str(path))


@pytest.mark.parametrize("name", list(FORMATS))
def test_published_schemas_are_generated_from_the_models(name):
    path = SCHEMAS / f"{name}.json"
    assert path.exists() and path.read_text() == schema_text(name), (
        f"{path} is stale: run python scripts/write_schemas.py"
    )


def test_every_shipped_yaml_file_is_covered():
    shipped = {p for paths in SHIPPED.values() for p in paths}
    every = {p for p in REPO.glob("*/**/*.yaml") if not any(part.startswith(".") for part in p.relative_to(REPO).parts)}
    assert every == shipped, sorted(str(p) for p in every ^ shipped)
    assert all(SHIPPED.values())


@pytest.mark.parametrize(
    ("name", "path"), [(n, p) for n, paths in SHIPPED.items() for p in paths], ids=lambda x: getattr(x, "name", x)
)
def test_shipped_file_names_its_schema_and_validates_against_it(name, path):
    match = SCHEMA_LINE.match(path.read_text())
    assert match, f"{path} must start with '# yaml-language-server: $schema=...'"
    assert (path.parent / match.group(1)).resolve() == (SCHEMAS / f"{name}.json").resolve()
    errors = [
        f"{list(e.absolute_path)}: {e.message}" for e in _validator(name).iter_errors(yaml.safe_load(path.read_text()))
    ]
    assert errors == []
    _load(name, path)


def _typo(doc: dict, keys: list, typo: str) -> dict:
    """``doc`` with the key at path ``keys`` renamed to ``typo``."""
    doc = copy.deepcopy(doc)
    parent = doc
    for k in keys[:-1]:
        parent = parent[k]
    parent[typo] = parent.pop(keys[-1])
    return doc


TYPOS = [
    ("scenario", REPO / "scenarios" / "battery_swap.yaml", ["vehicles", "shuttle", "start"], "strat", "start"),
    ("scenario", REPO / "scenarios" / "battery_swap.yaml", ["limits", "authority_fraction"], "authority", "authority_fraction"),
    ("model", REPO / "examples" / "models" / "neural-swarm.yaml", ["model", "thrust_scales"], "thrust_scale", "thrust_scales"),
    ("model", REPO / "examples" / "models" / "neural-swarm.yaml", ["vehicles", "crazyflie-2.1", "mass_kg"], "mass", "mass_kg"),
    ("truth", REPO / "examples" / "truth" / "all_effects.yaml", ["wind_mps"], "wind", "wind_mps"),
    ("manifest", REPO / "manifests" / "neural-swarm.yaml", ["flights", 0, "split"], "spilt", "split"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("name", "path", "keys", "typo", "meant"), TYPOS, ids=lambda x: x if isinstance(x, str) else None
)
def test_a_typo_fails_the_schema_and_the_loader_with_a_suggestion(tmp_path, name, path, keys, typo, meant):
    doc = _typo(yaml.safe_load(path.read_text()), keys, typo)
    assert list(_validator(name).iter_errors(doc)), "the schema accepted a misspelt key"
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc, sort_keys=False))
    if name == "truth":  # flightsim's own reader: rejects the key (no suggestion there yet)
        with pytest.raises(UserError, match=f"unknown key {typo!r}"):
            _load(name, bad)
        return
    with pytest.raises(UserError) as err:
        _load(name, bad)
    message = str(err.value)
    assert "\n" not in message and str(bad) in message
    where = ".".join(f"[{k}]" if isinstance(k, int) else k for k in [*keys[:-1], typo]).replace(".[", "[")
    assert f"{where}: unknown key (did you mean {meant!r}?)" in message, message


def test_vehicle_file_schema_requires_every_parameter_without_base(tmp_path):
    from proxplan.physics import BUILTIN_VEHICLES, vehicle_to_yaml_dict

    full = vehicle_to_yaml_dict(BUILTIN_VEHICLES["small-quad"])
    good = {"vehicles": {"a": {"base": "large-quad", "mass_kg": 0.9}, "b": full}}
    assert list(_validator("vehicles").iter_errors(good)) == []
    del full["propeller"]["diameter_m"]
    bad = {"vehicles": {"b": full}}
    assert list(_validator("vehicles").iter_errors(bad)), "schema accepted a vehicle without base and diameter"
    path = tmp_path / "v.yaml"
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(UserError, match=r"vehicles\.b\.propeller\.diameter_m: missing; expected a positive number"):
        _load("vehicles", path)


def test_written_plan_validates_against_the_plan_schema(battery_swap_plan):
    doc = json.loads((battery_swap_plan / "plan.json").read_text())
    assert [e.message for e in _validator("plan").iter_errors(doc)] == []
    doc["vehicles"]["shuttle"]["velocity_mps"][3] = [0.0, 1.0]
    assert list(_validator("plan").iter_errors(doc))


def test_schema_command_prints_writes_and_lists(tmp_path, proxplan):
    res = proxplan("schema", "scenario", "--json")
    assert res.returncode == 0 and json.loads(res.stdout) == json.loads(schema_text("scenario"))
    res = proxplan("schema", "model", "--out", tmp_path / "m.json")
    assert res.returncode == 0 and (tmp_path / "m.json").read_text() == schema_text("model")
    res = proxplan("schema", "vehicles")
    assert res.returncode == 0 and "propeller.diameter_m" in res.stdout and "m" in res.stdout
    res = proxplan("schema", "scenarios")
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "Traceback" not in res.stderr
