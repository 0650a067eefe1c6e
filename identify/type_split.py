"""A kept term's coefficient split by target vehicle type, where flights held out say one does not fit all
(issue 35).

A discovered term has ONE coefficient for every vehicle it acts on. A weight-scaled term is scaled by the
TARGET's weight W (force) or W L (torque, :func:`proxplan.physics.feature_terms.term_scale`), which makes one
coefficient describe a 32 g and a 650 g vehicle alike when the disturbance scales with the target's authority.
But how a neighbour's disturbance scales with the two vehicles' sizes is not known a priori: a torque that
scales with the SOURCE's size (a wider jet's shear across the target) is, per unit of the target's W L, L_src /
L_tgt times larger on a small target under a large source than on a large one (2.75x for the Parrot under the
large quads of bench draw 30001, 3.6x for draw 29001's Crazyflie: one shared coefficient was right for one
type and 2-3.6x wrong for the other). A wrench feature's coefficient (a copy of the base prediction) may differ
by type for the same reason.

So, once discovery has kept (and refined) its terms, each kept term acting on vehicles of two or more types
among the train flights is tested once more: the term with one coefficient per target type (its column masked
to each type's rows, keys ``"<key>@<type>"``, :func:`proxplan.physics.feature_terms.typed_key`) against the
term with one coefficient, both fitted beside the always-fitted columns and every other kept term, each train
flight predicted by the fit that did not see it (:func:`proxplan.identify.crossval.heldout_fit`). The split is
the larger model (the shared term is the split with equal coefficients), so it stands only where it passes the
gain test every term passes (:func:`proxplan.identify.heldout_select.gain_test` at
:data:`proxplan.identify.heldout_select.ALPHA`), Bonferroni over the kept terms tested (each one hypothesis: a
term whose coefficient does not depend on the type passes with probability at most ALPHA / m, so all of them
together with at most ALPHA). Nothing is searched (one alternative per term), so its held-out error is not
optimistic; no constant is set here. Terms are tested in the order kept, each given the earlier ones' accepted
splits.

A per-type term acts where the target's ``Vehicle.name`` is its type (:mod:`proxplan.physics.effects`): a split
is offered only where every type's vehicle in the model carries its type's name.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from proxplan.identify.crossval import HeldOutFit, Ridge, heldout_fit
from proxplan.identify.design import SelectionSet
from proxplan.identify.heldout_select import GainTest, gain_test
from proxplan.physics import term_type, typed_key

__all__ = ["TypeSplit", "split_by_type", "split_types"]


@dataclass(frozen=True)
class TypeSplit:
    """One kept term (``key``) tested with one coefficient per target type (``types``, the split's keys
    ``typed`` in that order) against one shared coefficient: ``test`` the gain test of the split over the shared
    term (``m`` the hypotheses it was corrected for), ``accepted`` whether the per-type terms stand in its place;
    ``columns`` the per-type columns (each (N, 4), noise units)."""

    key: str
    types: tuple[str, ...]
    typed: tuple[str, ...]
    test: GainTest
    m: int
    columns: dict[str, np.ndarray] = field(repr=False, compare=False)

    @property
    def accepted(self) -> bool:
        return self.test.passed

    def to_json(self) -> dict[str, object]:
        return {"key": self.key, "types": list(self.types), "typed_keys": list(self.typed), "m": self.m,
                "accepted": self.accepted, "test": self.test.to_json(),
                "test_of": "one coefficient per target type against one shared coefficient"}  # fmt: skip


def _row_types(sel: SelectionSet) -> np.ndarray:
    """(N,) each selection sample's target vehicle type."""
    return np.concatenate([np.full(len(u), u.type, dtype=object) for u in sel.units])


def split_types(sel: SelectionSet, column: np.ndarray) -> tuple[str, ...]:
    """The target types on whose train rows the term ``column`` ((N, 4), noise units) is not zero, in the model's
    order; () where the split cannot be expressed (a type's vehicle not named by its type) or the term is
    already typed."""
    if any(v.name != t for t, v in sel.model.vehicles.items()):
        return ()
    types = _row_types(sel)
    train = ~sel.plan.held_out_only[sel.group] & (sel.weight > 0)
    acting = train & np.any(column != 0.0, axis=1)
    present = set(types[acting])
    return tuple(t for t in sel.model.vehicles if t in present)


def split_by_type(
    sel: SelectionSet,
    fixed: Mapping[str, np.ndarray],
    kept: list[str],
    ridge_of: Callable[[tuple[str, ...]], Ridge],
) -> list[TypeSplit]:
    """Test each kept term of ``kept`` (keys among ``fixed``, name -> (N, 4) noise units: the always-fitted
    columns and every kept term) with one coefficient per target type (module docstring). Returns one
    :class:`TypeSplit` per term tested, accepted or not; a term acting on one type only is not tested."""
    row_types = _row_types(sel)
    offered = {k: split_types(sel, fixed[k]) for k in kept if term_type(k) is None}
    offered = {k: types for k, types in offered.items() if len(types) > 1}
    m = len(offered)
    columns = dict(fixed)
    out: list[TypeSplit] = []
    for key, types in offered.items():
        typed = tuple(typed_key(key, t) for t in types)
        split = {name: columns[key] * (row_types == t)[:, None] for name, t in zip(typed, types)}
        others = [k for k in columns if k != key]
        sums = sel.sums({**columns, **split})
        ridge = ridge_of(sums.columns)

        def fit(names: list[str]) -> HeldOutFit:
            return heldout_fit(sums, sums.index(names), sel.plan, ridge, sel.tau)  # noqa: B023

        test = gain_test(sums, fit([*others, key]), fit([*others, *typed]), m, cluster=sel.plan.cluster)
        record = TypeSplit(key, types, typed, test, m, split)
        out.append(record)
        if record.accepted:
            columns.pop(key)
            columns.update(split)
    return out
