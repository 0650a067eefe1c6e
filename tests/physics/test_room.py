"""Planes of the room (proxplan.physics.room) and their manifest keys: distances and one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.fileio import UserError
from proxplan.physics import plane_distances_m, planes_from_list


def test_plane_distance_is_signed_along_the_normalised_normal_and_clipped_behind() -> None:
    (wall,) = planes_from_list([{"name": "w", "point_m": [2.0, 0, 0], "normal": [-3.0, 0, 0]}], "m.yaml: planes")
    assert wall.normal == (-1.0, 0.0, 0.0)
    pos = np.array([[1.5, 0.3, 1.0], [2.5, 0.0, 0.0]])
    np.testing.assert_allclose(wall.distance_m(pos), [0.5, -0.5])
    np.testing.assert_allclose(plane_distances_m((wall,), pos)[:, 0], [0.5, 0.0])


@pytest.mark.parametrize(
    "raw",
    [
        {"point_m": [0, 0, 0]},  # not a list
        [{"point_m": [0, 0], "normal": [0, 0, 1]}],  # point of two numbers
        [{"point_m": [0, 0, 0], "normal": [0, 0, 0]}],  # zero normal
        [{"normal": [0, 0, 1]}],  # no point
    ],
)
def test_malformed_planes_are_one_line_errors_naming_the_key(raw) -> None:
    with pytest.raises(UserError, match=r"m\.yaml: planes") as err:
        planes_from_list(raw, "m.yaml: planes")
    assert "\n" not in str(err.value)


def test_manifest_motor_thrust_is_checked(tmp_path) -> None:
    from proxplan.identify import load_manifest

    (tmp_path / "a.csv").write_text("t\n")
    path = tmp_path / "m.yaml"
    path.write_text(
        "format: canonical\nroot: .\nmotor_thrust: lagged\nflights:\n"
        "- {name: f, split: test, vehicles: {a: {type: small-quad, log: a.csv}}}\n"
    )
    with pytest.raises(UserError, match="motor_thrust: expected one of commanded, delivered"):
        load_manifest(path, require_train_and_test=False)
