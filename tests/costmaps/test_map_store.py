"""Map store: parameter hash, save/load round trip, mismatch detection, shipped maps up to date."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from proxplan.costmaps import (
    DATA_DIR,
    FORMAT_VERSION,
    build_pair_maps,
    load_pair_maps,
    pair_maps,
    param_hash,
    save_pair_maps,
    shipped_path,
)
from proxplan.fileio import UserError
from proxplan.physics import BUILTIN_VEHICLES, ModelOptions
from proxplan.physics.geometry import Discretisation

SMALL, LARGE = BUILTIN_VEHICLES["small-quad"], BUILTIN_VEHICLES["large-quad"]


@pytest.fixture(scope="module")
def maps():
    return build_pair_maps(SMALL, LARGE)


def test_hash_changes_with_any_parameter():
    base = param_hash(SMALL, LARGE)
    changed = [
        param_hash(dataclasses.replace(SMALL, mass_kg=SMALL.mass_kg * 1.01), LARGE),
        param_hash(SMALL, dataclasses.replace(LARGE, downwash=dataclasses.replace(LARGE.downwash, c_rad=25.0))),
        param_hash(
            SMALL, dataclasses.replace(LARGE, propeller=dataclasses.replace(LARGE.propeller, b_v_measured=3.8e-7))
        ),
        param_hash(SMALL, dataclasses.replace(LARGE, frame=dataclasses.replace(LARGE.frame, arm_width_m=0.02))),
        param_hash(SMALL, LARGE, ModelOptions(field_form="printed")),
        param_hash(SMALL, LARGE, ModelOptions(discretisation=Discretisation(disk_rings=5))),
        param_hash(LARGE, SMALL),  # order matters: source above, target below
    ]
    assert len({base, *changed}) == len(changed) + 1
    # free text does not change the numbers, so it does not invalidate maps
    assert param_hash(dataclasses.replace(SMALL, description="renamed note"), LARGE) == base


def test_round_trip_keeps_numbers(maps, tmp_path):
    path = save_pair_maps(maps, tmp_path / "pair.npz")
    loaded = load_pair_maps(path, expect_source=SMALL, expect_target=LARGE)
    assert loaded.metadata["param_hash"] == maps.metadata["param_hash"]
    assert loaded.metadata["format_version"] == FORMAT_VERSION
    dz = np.linspace(0.0, 4.0, 57)
    for level in (0.02, 0.033, 0.5):
        assert np.allclose(loaded.cutoff.r_cut_m(dz, level=level), maps.cutoff.r_cut_m(dz, level=level), atol=1e-5)
    rng = np.random.default_rng(0)
    offsets = np.column_stack([rng.normal(0, 0.2, 300), rng.normal(0, 0.2, 300), -rng.uniform(0.3, 3.0, 300)])
    f0, t0 = maps.table.wrench_numpy(offsets)
    f1, t1 = loaded.table.wrench_numpy(offsets)
    assert np.abs(f0).max() > 0
    assert np.allclose(f1, f0, atol=1e-6 * np.abs(f0).max())
    assert np.allclose(t1, t0, atol=1e-6 * np.abs(t0).max())
    with np.load(path) as npz:  # DESIGN.md section 4 keys
        assert npz["dz_m"].shape == npz["r_cut_m"].shape
        assert npz["cutoff_usage"].dtype == np.float32


def test_mismatch_and_bad_files_are_user_errors(maps, tmp_path):
    path = save_pair_maps(maps, tmp_path / "pair.npz")
    heavier = dataclasses.replace(SMALL, mass_kg=0.2)
    with pytest.raises(UserError, match=r"mass_kg"):
        load_pair_maps(path, expect_source=heavier, expect_target=LARGE)
    with pytest.raises(UserError, match="other parameters"):
        load_pair_maps(path, expect_source=SMALL, expect_target=LARGE, options=ModelOptions(field_form="printed"))
    with pytest.raises(UserError, match="no such"):
        load_pair_maps(tmp_path / "missing.npz")
    junk = tmp_path / "junk.npz"
    junk.write_text("not a zip")
    with pytest.raises(UserError, match="not a readable"):
        load_pair_maps(junk)
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["format_version"] = np.array(FORMAT_VERSION - 1)
    old = tmp_path / "old.npz"
    np.savez(old, **arrays)
    with pytest.raises(UserError, match="format version"):
        load_pair_maps(old)
    del arrays["cutoff_usage"]
    arrays["format_version"] = np.array(FORMAT_VERSION)
    np.savez(tmp_path / "partial.npz", **arrays)
    with pytest.raises(UserError, match="missing keys"):
        load_pair_maps(tmp_path / "partial.npz")
    with pytest.raises(UserError, match=".npz"):
        save_pair_maps(maps, tmp_path / "pair.txt")


def test_shipped_maps_match_the_model_parameters():
    """Fails when a built-in vehicle, the model options or the format change without regenerating
    the shipped maps: `proxplan costmap --all --out-dir costmaps/data`."""
    stale = []
    for s_name, source in BUILTIN_VEHICLES.items():
        for t_name, target in BUILTIN_VEHICLES.items():
            path = shipped_path(s_name, t_name)
            assert path.exists(), f"missing shipped map {path}"
            try:
                load_pair_maps(path, expect_source=source, expect_target=target)
            except UserError as err:
                stale.append(str(err))
    assert not stale, (
        "stale shipped maps; regenerate with `proxplan costmap --all --out-dir costmaps/data`:\n" + "\n".join(stale)
    )
    total = sum(p.stat().st_size for p in DATA_DIR.glob("*.npz"))
    assert total < 6e6, f"shipped maps take {total / 1e6:.1f} MB"


def test_pair_maps_uses_shipped_map_and_computes_custom_vehicles():
    shipped = pair_maps(SMALL, LARGE)
    with np.load(shipped_path("small-quad", "large-quad")) as npz:
        stored = json.loads(str(npz["metadata_json"]))
    assert shipped.metadata == stored  # came from the shipped file
    assert pair_maps(SMALL, LARGE) is shipped  # cached
    calibrated = dataclasses.replace(LARGE, propeller=dataclasses.replace(LARGE.propeller, b_v_measured=7.4e-7))
    custom = pair_maps(SMALL, calibrated)
    assert custom.metadata["param_hash"] == param_hash(SMALL, calibrated)
    # doubling b_v raises the thrust-change disturbance, so the cutoff at a low level widens
    dz = np.array([1.0, 2.0])
    assert np.all(custom.cutoff.r_cut_m(dz, level=0.02) > shipped.cutoff.r_cut_m(dz, level=0.02))


def test_shipped_data_dir_is_inside_the_package():
    assert DATA_DIR == Path(__file__).resolve().parents[2] / "costmaps" / "data"
