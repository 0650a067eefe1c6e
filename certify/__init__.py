"""Certification of a plan: Monte-Carlo closed-loop flights (flightsim) under model uncertainty,
residual disturbance, sensor noise, start and timing errors, fanned out on Dask (fanout); the
probabilities of exceeding authority, violating separation and missing the goal with Wilson 95 %
intervals, and a report.
"""

from proxplan.certify.draws import DEFAULT_RELATIVE_SPREADS, MODEL_PARAMETERS, NoiseSpec, RunDraw, Spreads, draw_run
from proxplan.certify.engine import CertifyResult, certify_plan, summarise_runs
from proxplan.certify.report import write_report
from proxplan.certify.run import DEFAULT_GOAL_TOLERANCE_M, CertifySetup, fly_run
from proxplan.certify.stats import percentiles, probability, wilson_interval

__all__ = [
    "DEFAULT_GOAL_TOLERANCE_M",
    "DEFAULT_RELATIVE_SPREADS",
    "MODEL_PARAMETERS",
    "CertifyResult",
    "CertifySetup",
    "NoiseSpec",
    "RunDraw",
    "Spreads",
    "certify_plan",
    "draw_run",
    "fly_run",
    "percentiles",
    "probability",
    "summarise_runs",
    "wilson_interval",
    "write_report",
]
