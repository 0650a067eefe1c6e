"""A side-axis torque term also tested in its LEVER form: the force at its lever arm (issue 35, round 37K).

A multi-scale kernel times the offset's x or y over the NEIGHBOUR's size L (``..._y_1``,
:mod:`proxplan.physics.basis`) on a torque channel is the term c W L_t k y / L: the target's W L_t
(:func:`proxplan.physics.feature_terms.term_scale`) times the lever arm y rescaled by L_t / L. Its coefficient
then depends on the pair of sizes. Where a neighbour's force c W k acts off the target's centre, its torque is
c W k y, the lever arm in metres, whatever the two sizes: the lever form ``..._yt_1``
(:data:`proxplan.physics.basis.LEVER_AXES`, offset over the TARGET's size, so that W L_t times it is W k y).
Which law a disturbance follows is not known a priori; with two vehicle types one coefficient per target type
(:mod:`proxplan.identify.type_split`) fits either law, but with three a target under two neighbours of different
sizes needs two coefficients for one type, and a type that the train flights barely expose gets a coefficient
the data do not inform (bench block 34000, draws 6 and 11: a roll torque 0.02 W k tanh(y / L) L from a
neighbour below / above, left at 1.41x and 2.26x its clean twin's torque by the per-type form on all three
types; the lever form with one coefficient, fitted noise-free on the exact motions, would leave 1.04x and
1.06x).

So a stable weight-scaled torque term on a side axis is also offered in its lever form, as an ALTERNATIVE of
the same hypothesis (the Bonferroni count is unchanged), where the model's vehicles are of two or more sizes
(with one size the two forms are the same column). It has one column like the original; the forward pass keeps
it over the original only where both pass and the flights show it better head to head
(:func:`proxplan.identify.heldout_select.heldout_forward`'s ``alternatives``: of two forms of one term with as
many columns, the one offered first is kept unless the other beats it), and the per-type form only where it
beats both. No constant is set here.
"""

from __future__ import annotations

from collections.abc import Sequence

from proxplan.identify.design import SelectionSet
from proxplan.physics import LEVER_AXES, parse_basis_name, parse_term_key, term_type, weight_scaled

__all__ = ["lever_forms", "lever_key"]


def lever_key(key: str) -> str | None:
    """The lever form of term ``key`` (the same channel and kernel, its side axis over the target's size), None
    where ``key`` is not a weight-scaled, untyped torque term on a multi-scale kernel's x or y axis."""
    if term_type(key) is not None or not weight_scaled(key):
        return None
    channel, feature = parse_term_key(key)
    parsed = parse_basis_name(feature)
    if not channel.startswith("torque") or parsed is None or parsed[1] not in LEVER_AXES:
        return None
    return key[: -len(feature)] + parsed[0].name(LEVER_AXES[parsed[1]])


def lever_forms(sel: SelectionSet, keys: Sequence[str]) -> dict[str, str]:
    """Term key -> its lever form, for every term of ``keys`` that has one (:func:`lever_key`), where the model's
    vehicles are of two or more sizes; {} otherwise."""
    if len({v.size_m for v in sel.model.vehicles.values()}) < 2:
        return {}
    return {k: lk for k in keys if (lk := lever_key(k)) is not None}
