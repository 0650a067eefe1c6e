"""Which vehicle parameters earn a recalibration, judged by flights held out (issue 35).

The selection around the PRIOR model (:func:`proxplan.identify.selection.select_and_discover`, ``start="prior"``)
is the alternative to the calibration: the model as built, its parameters moved only where that carries over
to flights the fit did not see. A calibration fits every declared parameter (c_ax, z0_m, c_rad of a source
type; b_v of a target type; the stack shielding eta) on every train flight. Where the data hold an effect the
model lacks, the parameters take what they can of it: on generated logs with a force from a neighbour
BESIDE a Parrot (bench_discovery draw 5006) the large quad's c_ax moved 2.4 prior sigmas, its z0 1.7, c_rad
onto its bound; the Parrot's test error went from 5.1 mN with the model as built to 9.7 mN, and the
discovery search, run on what the tangents left, found nothing.

So at the prior start the parameters enter as groups, and a group is HELD at its prior (no tangent, no step,
no polish) when its recalibration predicts the flights held out worse than the prior does: given the other
groups and the thrust scales (always fitted: a nuisance, :mod:`proxplan.identify.effect_selection`), the
held-out error it removes, summed over the flights, is negative (R < 0 in the gain test of
:mod:`proxplan.identify.heldout_select`; every flight predicted by a fit without it). Backward, the worst
first, until every group left removes error. The calibration's MAP step is the default, and it is undone only
where the flights say it does not carry over: the choice between two predictors by held-out error, as
between the two starts (:func:`proxplan.identify.selection.other_start_better`), with no significance
margin (a significance test would hold a useful step the flights cannot yet prove: on the swept wake of
tests/identify/test_discovery.py the small quad's b_v step removes held-out error, R = 0.46 +- 0.35, and
holding it took the test error from within 1.3x of the clean twin's to 1.39x). Groups:

* ``"<type> as a source"``: c_ax, z0_m, c_rad of that type (the jet it makes);
* ``"<type> as a target"``: b_v of that type (the frame drag it meets);
* ``"stack shielding"``: eta.

On draw 5006 the large quad's source group is held (R = -2.4 +- 0.3 over 3 flights). A group that acts on no
held-out flight has no test and stays with the calibration (its prior then holds it anyway). No constant is
added.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from proxplan.identify.calibrate import STACK_PARAMETER, ParamSpec
from proxplan.identify.crossval import GroupPlan, GroupSums, HeldOutFit, Ridge, heldout_fit
from proxplan.identify.design import is_thrust_scale
from proxplan.identify.heldout_select import GainTest, gain_test

__all__ = ["EarnedParameters", "backward_by_heldout_error", "earned_parameters", "parameter_group"]


def parameter_group(name: str) -> str:
    """The group (one hypothesis) a calibrated parameter ``name`` (``TYPE.param``) belongs to (module docstring)."""
    if name == STACK_PARAMETER:
        return "stack shielding"
    vtype, key = name.rsplit(".", 1)
    return f"{vtype} as a target" if key == "b_v" else f"{vtype} as a source"


@dataclass
class EarnedParameters:
    """The groups kept (their recalibration removes held-out error), the parameter names held at their
    priors (``held``), and the backward pass's record: per round, group -> its gain test given the others."""

    kept: list[str]
    held: frozenset[str]
    rounds: list[dict[str, GainTest]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"kept_groups": list(self.kept), "held_at_prior": sorted(self.held),
                "rounds": [{g: t.to_json() for g, t in r.items()} for r in self.rounds]}  # fmt: skip


def earned_parameters(selector) -> EarnedParameters:
    """The groups of ``selector``'s vehicle parameters (an :class:`proxplan.identify.effect_selection.EffectSelector`
    around the prior model) whose recalibration predicts the held-out flights better than their priors, given
    the others (module docstring)."""
    specs: Sequence[ParamSpec] = selector.specs
    nuisance = [s.name for s in specs if is_thrust_scale(s)]
    groups: dict[str, list[str]] = {}
    for s in specs:
        if not is_thrust_scale(s):
            groups.setdefault(parameter_group(s.name), []).append(s.name)
    sel = selector.sel
    sums = sel.sums({k: selector.tangents[k] for k in selector.always})
    kept, rounds = backward_by_heldout_error(
        sums, sel.plan, selector.ridge_for(sums.columns), sel.tau, nuisance, groups
    )
    held = frozenset(n for g, names in groups.items() if g not in kept for n in names)
    return EarnedParameters(kept, held, rounds)


def backward_by_heldout_error(
    sums: GroupSums,
    plan: GroupPlan,
    ridge: Ridge,
    tau: float,
    always: Sequence[str],
    groups: Mapping[str, Sequence[str]],
) -> tuple[list[str], list[dict[str, GainTest]]]:
    """Backward elimination of column ``groups`` (name -> columns of ``sums``) fitted beside ``always``: while
    some group, given the others, predicts the held-out flights worse than without it (the gain test's
    R < 0; a group acting on no held-out flight is not judged), the worst is dropped. Returns the groups kept
    (in ``groups``' order) and each round's tests (group -> :class:`~proxplan.identify.heldout_select.GainTest`)."""

    def fitted(names: Sequence[str]) -> HeldOutFit:
        cols = [*always, *(c for g in names for c in groups[g])]
        return heldout_fit(sums, sums.index(cols), plan, ridge, tau)

    kept = list(groups)
    rounds: list[dict[str, GainTest]] = []
    while kept:
        current = fitted(kept)
        tests = {g: gain_test(sums, fitted([k for k in kept if k != g]), current, 1, None, plan.cluster) for g in kept}
        rounds.append(tests)
        worst = min((g for g in kept if tests[g].n_groups > 0), key=lambda g: tests[g].mean, default=None)
        if worst is None or tests[worst].mean >= 0.0:
            break
        kept.remove(worst)
    return kept, rounds
