"""Which vehicle parameters earn a recalibration, judged by flights held out (issue 35).

The selection around the PRIOR model (:func:`proxplan.identify.selection.select_and_discover`, ``start="prior"``)
is the alternative to the calibration: the model as built, its parameters moved only where that carries over
to flights the fit did not see. A calibration fits every declared parameter (c_ax, z0_m, c_rad of a source
type; b_v of a target type; the stack shielding eta) on every train flight. Where the data hold an effect the
model lacks, the parameters take what they can of it: on generated logs with a force from a neighbour
BESIDE a Parrot (bench_discovery draw 5006) the large quad's c_ax moved 2.4 prior sigmas, its z0 1.7, c_rad
onto its bound; the Parrot's test error went from 5.1 mN with the model as built to 9.7 mN, and the
discovery search, run on what the tangents left, found nothing.

So at the prior start the parameters enter as groups, one hypothesis each, tested like any candidate: the
group's tangent columns (first order about the prior, with their priors as ridge;
:func:`proxplan.identify.design.tangent_columns`) by the held-out gain test of
:mod:`proxplan.identify.heldout_select` (forward, Bonferroni over the groups, then backward), beside the
thrust scales, which are always fitted (a nuisance: :mod:`proxplan.identify.effect_selection`). A group that
does not pass is HELD at its prior for that start: no tangent, no step, no polish. Groups:

* ``"<type> as a source"``: c_ax, z0_m, c_rad of that type (the jet it makes);
* ``"<type> as a target"``: b_v of that type (the frame drag it meets);
* ``"stack shielding"``: eta.

On draw 5006 no group passes (the source group's held-out ratio R = 0.42 +- 2.0 over 3 flights); on the
shipped Neural-Swarm manifest the Parrot's source group passes first (R = 0.95, t = 4.8 against 2.6).
No constant is added: the level is the gain test's (:data:`proxplan.identify.heldout_select.ALPHA`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from proxplan.identify.calibrate import STACK_PARAMETER, ParamSpec
from proxplan.identify.design import is_thrust_scale
from proxplan.identify.heldout_select import Candidate, ForwardResult, heldout_forward

__all__ = ["EarnedParameters", "earned_parameters", "parameter_group"]


def parameter_group(name: str) -> str:
    """The group (one hypothesis) a calibrated parameter ``name`` (``TYPE.param``) belongs to (module docstring)."""
    if name == STACK_PARAMETER:
        return "stack shielding"
    vtype, key = name.rsplit(".", 1)
    return f"{vtype} as a target" if key == "b_v" else f"{vtype} as a source"


@dataclass
class EarnedParameters:
    """The groups whose recalibration carried over to held-out flights (``kept``), the parameter names
    held at their priors (``held``), and the forward pass's record (every round's gain tests)."""

    kept: list[str]
    held: frozenset[str]
    forward: ForwardResult = field(default_factory=ForwardResult)

    def to_json(self) -> dict[str, Any]:
        last: dict[str, Any] = {}
        for tests in self.forward.tests:
            last.update(tests)
        last.update(self.forward.final_tests)
        return {"kept_groups": list(self.kept), "held_at_prior": sorted(self.held),
                "tests": {g: t.to_json() for g, t in last.items()}}  # fmt: skip


def earned_parameters(selector) -> EarnedParameters:
    """The groups of ``selector``'s vehicle parameters (an :class:`proxplan.identify.effect_selection.EffectSelector`
    around the prior model) whose tangents pass the held-out gain test beside the thrust scales (module
    docstring)."""
    specs: Sequence[ParamSpec] = selector.specs
    nuisance = [s.name for s in specs if is_thrust_scale(s)]
    groups: dict[str, list[str]] = {}
    for s in specs:
        if not is_thrust_scale(s):
            groups.setdefault(parameter_group(s.name), []).append(s.name)
    if not groups:
        return EarnedParameters([], frozenset())
    sel = selector.sel
    sums = sel.sums({k: selector.tangents[k] for k in selector.always})
    ridge = selector.ridge_for(sums.columns)
    fwd = heldout_forward(sums, nuisance, [Candidate(g, tuple(names)) for g, names in groups.items()], sel.plan,
                          ridge, sel.tau, max_terms=len(groups))  # fmt: skip
    held = frozenset(n for g, names in groups.items() if g not in fwd.chosen for n in names)
    return EarnedParameters(list(fwd.chosen), held, fwd)
