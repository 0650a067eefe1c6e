"""A term tested with one coefficient per target vehicle type beside the term with one coefficient (issue 35).

A discovered term has ONE coefficient for every vehicle it acts on. A weight-scaled term is scaled by the
TARGET's weight W (force) or W L (torque, :func:`proxplan.physics.feature_terms.term_scale`), which makes one
coefficient describe a 32 g and a 650 g vehicle alike when the disturbance scales with the target's authority.
But how a neighbour's disturbance scales with the two vehicles' sizes is not known a priori: a torque that
scales with the SOURCE's size is, per unit of the target's W L, L_src / L_tgt times larger on a small target
under a large source than on a large target under a small one (bench draw 31006: a roll torque from the quad
above, on the small quad in two train flights and on the large quad in four, needs coefficients 7.95x apart;
one shared coefficient fitted the small quad's flights and made the large quad's worse, so no member of the
stable group passed, t <= 2.55 against z 2.57, while the same feature with one coefficient per target type
passed at t = 38; draws 29001 and 30001: a kept term right for one type and 2-3.6x wrong for the other). A
wrench feature's coefficient (a copy of the base prediction) may differ by type for the same reason.

So every candidate term that acts on vehicles of two or more types among the train flights is offered in a
second form, its column masked to each target type's rows (keys ``"<key>@<type>"``,
:func:`proxplan.physics.feature_terms.typed_key`), as ONE candidate of several columns
(:class:`TypeSplit`, named :func:`split_name`). The two forms test one hypothesis (the term's group, so the
Bonferroni count is unchanged: the same as several members of one group, each a form of one effect) and are
ALTERNATIVES: once one is kept the other leaves the search, so a term is never kept twice; and the per-type
form competes in a round only where it passes and, where the one-coefficient form passes too, beats it head to
head (:func:`proxplan.identify.heldout_select.heldout_forward`): where no per-type form is needed, the rounds are
the rounds without them, and a near tie never splits a term. The per-type form has K - 1 more coefficients; the
gain test judges each flight by the fit that did not see it, so coefficients the data do not inform cost held-out
error rather than win it. Its typed keys are
refined, kept and dropped together (:mod:`proxplan.identify.selection`'s backward pass). No constant is set
here.

A per-type term acts where the target's ``Vehicle.name`` is its type (:mod:`proxplan.physics.effects`): the
split is offered only where every type's vehicle in the model carries its type's name.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.identify.design import SelectionSet
from proxplan.physics import term_type, typed_key

__all__ = ["SPLIT_SUFFIX", "TypeSplit", "split_candidates", "split_name", "split_types"]

SPLIT_SUFFIX = " per target type"
"""A split candidate's name is its term key and this (not a term key: the candidate stands for its typed keys)."""


def split_name(key: str) -> str:
    """The candidate name of term ``key`` with one coefficient per target type."""
    return f"{key}{SPLIT_SUFFIX}"


@dataclass(frozen=True)
class TypeSplit:
    """Term ``key`` with one coefficient per target type ``types``: the typed keys ``typed`` (in that order) and
    their columns (each (N, 4), noise units: the term's column on that type's rows, zero elsewhere)."""

    key: str
    types: tuple[str, ...]
    typed: tuple[str, ...]
    columns: dict[str, np.ndarray] = field(repr=False, compare=False)

    @property
    def name(self) -> str:
        return split_name(self.key)


def split_types(sel: SelectionSet, column: np.ndarray) -> tuple[str, ...]:
    """The target types on whose train rows the term ``column`` ((N, 4), noise units) is not zero, in the model's
    order; () where a type's vehicle in the model is not named by its type (a per-type key could not act)."""
    if any(v.name != t for t, v in sel.model.vehicles.items()):
        return ()
    train = ~sel.plan.held_out_only[sel.group] & (sel.weight > 0)
    present = set(sel.target_types()[train & np.any(column != 0.0, axis=1)])
    return tuple(t for t in sel.model.vehicles if t in present)


def split_candidates(sel: SelectionSet, keys: Sequence[str], columns: Mapping[str, np.ndarray]) -> list[TypeSplit]:
    """The per-type form of every term of ``keys`` (untyped keys of ``columns``, name -> (N, 4) noise units) that
    acts on two or more target types among the train flights."""
    types_of_row = sel.target_types()
    out = []
    for key in keys:
        if term_type(key) is not None:
            continue
        types = split_types(sel, columns[key])
        if len(types) < 2:
            continue
        typed = tuple(typed_key(key, t) for t in types)
        out.append(TypeSplit(key, types, typed,
                             {k: columns[key] * (types_of_row == t)[:, None] for k, t in zip(typed, types)}))  # fmt: skip
    return out
