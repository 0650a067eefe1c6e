"""``run_identify`` with its independent stages beside each other (``IdentifyOptions.workers``, a
worker process of proxplan.fanout.background) gives the same result as all in one process."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from proxplan.identify import run_identify

from .test_identify import FAST, HIDDEN, make_manifest


def _json(result) -> dict:
    doc = json.loads(json.dumps(result.to_json(), default=float))
    doc.pop("timings_s")
    return doc


def test_two_processes_give_the_result_of_one(tmp_path: Path) -> None:
    manifest = make_manifest(tmp_path, (HIDDEN["near_field"],), duration_s=10.0)
    options = replace(FAST, effects=("thrust_bias", "ground_effect", "near_field", "own_velocity"))  # a few: fast
    one = run_identify(manifest, options=options, thrust_summary=False)
    two = run_identify(manifest, options=replace(options, workers=2), thrust_summary=False)
    assert one.selected == two.selected and len(one.selected) > 1  # something beyond thrust_bias was kept
    assert _json(one) == _json(two)
    for stage in ("selection around the calibrated model", "selection around the prior model", "motor lag check"):
        assert two.timings[stage] > 0.0
