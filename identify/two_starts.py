"""The selections around the calibrated and the prior model (:mod:`proxplan.identify.pipeline`, stage 5-6),
in this process or side by side on Dask workers (:mod:`proxplan.fanout`).

The two selections are independent: each starts from its own reference model, on the same train, validation
and test samples, in the same noise units; only their comparison
(:func:`proxplan.identify.selection.other_start_better`) needs both. Each is a deterministic function of its
:class:`SelectionJob` and runs with one BLAS thread wherever it runs (:func:`proxplan.physics.one_blas_thread`:
no sum depends on the machine's thread count), so the results are the same, bit for bit, run here one after
the other or on two workers (tests/identify/test_two_starts.py). On two cores the selections are most of
identify's time, and side by side they take about the longer one's wall time instead of the sum.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

from proxplan.identify.calibrate import ParamSpec
from proxplan.identify.data import IdentifyOptions, Model, Unit, progress_bar
from proxplan.identify.noise import NoiseLevel
from proxplan.identify.selection import Selection, select_and_discover
from proxplan.physics import one_blas_thread

__all__ = ["SelectionJob", "StartResult", "run_starts"]


@dataclass(frozen=True)
class SelectionJob:
    """Everything one selection reads (the arguments of :func:`proxplan.identify.selection.select_and_discover`)."""

    fit: Sequence[Unit]  # train units (every sample; the selection draws its stratified sample)
    valid: Sequence[Unit]  # validation units
    reference: Model  # the model selection starts from
    specs: Sequence[ParamSpec]  # the vehicle parameters refitted beside every candidate
    options: IdentifyOptions
    noise: NoiseLevel  # the noise units both starts share
    test: Sequence[Unit]  # test samples each candidate is also reported on (never chosen on)
    start: str  # "calibrated" or "prior"
    calibrated_thrust_scale: Mapping[str, float] | None
    prior_model: Model | None  # the calibration's priors (for the polish)


@dataclass(frozen=True)
class StartResult:
    """One start's selection and its own wall time, s."""

    selection: Selection
    wall_s: float


@one_blas_thread
def run_job(job: SelectionJob) -> StartResult:
    """One selection (one BLAS thread, in whichever process runs it)."""
    t0 = time.perf_counter()
    sel = select_and_discover(job.fit, job.valid, job.reference, job.specs, options=job.options, noise=job.noise,
                              test=job.test, start=job.start, calibrated_thrust_scale=job.calibrated_thrust_scale,
                              prior_model=job.prior_model)  # fmt: skip
    return StartResult(sel, time.perf_counter() - t0)


def run_starts(jobs: Sequence[SelectionJob], *, workers: int) -> list[StartResult]:
    """Each job's selection, in the order of ``jobs``: on ``min(workers, len(jobs))`` Dask workers on this
    machine when that is at least 2, else here one after the other. Progress bars of a job fanned out are off
    (a worker's bars would interleave); a bar counts the selections done instead."""
    if workers < 2 or len(jobs) < 2:
        return [run_job(job) for job in jobs]
    from proxplan.fanout import fan_out

    quiet = [replace(job, options=replace(job.options, progress=False)) for job in jobs]
    enabled = jobs[0].options.progress
    bar = progress_bar(range(len(jobs)), "selections (starts side by side)", enabled)
    update = getattr(bar, "update", None)
    done = fan_out(run_job, quiet, n_workers=min(workers, len(jobs)),
                   progress=(lambda d, n: update(1)) if update is not None else None)  # fmt: skip
    if hasattr(bar, "close"):
        bar.close()
    return done.results
