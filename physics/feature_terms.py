"""Discovered terms' parameter names, scales and formulas (:mod:`proxplan.physics.features` holds the features).

A discovered term is ``Effect("discovered:<label>", params)``; every parameter is named
``"<channel>*<feature>"`` (a feature that already is a force or torque: the coefficient in channel units per
feature unit) or ``"<channel>*W*<feature>"`` (a shape scaled to the target vehicle, :func:`term_scale`).
Either may end in ``"@<type>"`` (:func:`typed_key`): the term then acts on vehicles of that type only (its
``Vehicle.name``), one coefficient per target type where one shared coefficient did not describe them all
(:mod:`proxplan.identify.type_split`).
"""

from __future__ import annotations

from proxplan.physics.features import CHANNELS, TARGET_ONLY_FEATURES, is_feature
from proxplan.physics.vehicles import Vehicle

WRENCH_UNITS = ("N", "Nm", "Nmps")
"""Unit suffixes of features that are already a force or torque (the base prediction and its copies, the
thrust from the motion): a term on them is ``coefficient x feature``. Every other feature (a kernel, a
speed) is a shape; a term on it is scaled to the target vehicle (:func:`term_scale`)."""
WEIGHT_MARK = "W"
"""A term key ``"<channel>*W*<feature>"`` is ``coefficient x feature x`` :func:`term_scale`."""
TYPE_MARK = "@"
"""A term key ``"<key>@<type>"`` acts on target vehicles of that type only (:func:`typed_key`)."""


def is_wrench_feature(name: str) -> bool:
    """Whether feature ``name`` is already a force or torque (:data:`WRENCH_UNITS`)."""
    return name.rsplit("_", 1)[-1] in WRENCH_UNITS


def term_scale(channel: str, target: Vehicle) -> float:
    """What a shape feature is multiplied by in a weight-scaled term on ``channel``: the target's weight W (N)
    for a force, W times its size L (N m) for a torque. A disturbance the controller must reject is
    measured against its authority, which scales with W: one coefficient then describes a 32 g and a 650 g
    vehicle alike."""
    return target.weight_N * (target.size_m if channel.startswith("torque") else 1.0)


def term_key(channel: str, feature: str) -> str:
    """The parameter name of a term: ``"<channel>*<feature>"`` for a wrench feature, else the weight-scaled
    ``"<channel>*W*<feature>"``."""
    return f"{channel}*{feature}" if is_wrench_feature(feature) else f"{channel}*{WEIGHT_MARK}*{feature}"


def typed_key(key: str, vehicle_type: str) -> str:
    """The term ``key`` restricted to target vehicles of type ``vehicle_type`` (``"<key>@<type>"``)."""
    if term_type(key) is not None:
        raise ValueError(f"discovered-term parameter {key!r} already names a target type")
    return f"{key}{TYPE_MARK}{vehicle_type}"


def term_type(key: str) -> str | None:
    """The target vehicle type a term acts on (``"<key>@<type>"``), None for every target."""
    _, mark, vehicle_type = key.partition(TYPE_MARK)
    return vehicle_type if mark else None


def untyped_key(key: str) -> str:
    """``key`` without its target type (:func:`typed_key`)."""
    return key.partition(TYPE_MARK)[0]


def parse_term_key(key: str) -> tuple[str, str]:
    """Split a discovered-term parameter name ``"<channel>*<feature>"`` (or the weight-scaled
    ``"<channel>*W*<feature>"``, :func:`weight_scaled`; either may end in ``"@<type>"``, :func:`typed_key`) into
    channel and feature; ValueError if unknown."""
    if term_type(key) == "":
        raise ValueError(f"discovered-term parameter {key!r}: expected a vehicle type after '{TYPE_MARK}'")
    channel, sep, feature = untyped_key(key).partition("*")
    if feature.startswith(WEIGHT_MARK + "*"):
        feature = feature[len(WEIGHT_MARK) + 1 :]
    if not sep or channel not in CHANNELS or not is_feature(feature):
        raise ValueError(
            f"discovered-term parameter {key!r}: expected '<channel>*<feature>' or '<channel>*W*<feature>' (either "
            f"optionally ending in '{TYPE_MARK}<vehicle type>') with channel one of {', '.join(CHANNELS)} and a feature of proxplan.physics.features.FEATURE_NAMES (a "
            "multi-scale kernel at any scale)"
        )
    return channel, feature


def weight_scaled(key: str) -> bool:
    """Whether the term ``key`` is scaled to the target vehicle (:func:`term_scale`)."""
    return key.partition("*")[2].startswith(WEIGHT_MARK + "*")


def term_formula(params: dict[str, float]) -> str:
    """Human-readable formula of a discovered term, one line per channel."""
    by_channel: dict[str, list[str]] = {}
    for key, coef in params.items():
        channel, feature = parse_term_key(key)
        scale = (" * W * L" if channel.startswith("torque") else " * W") if weight_scaled(key) else ""
        only = "" if term_type(key) is None else f" [on {term_type(key)}]"
        by_channel.setdefault(channel, []).append(f"{coef:+.4g}{scale} * {feature}{only}")
    return "; ".join(f"{c} = {' '.join(terms)}" for c, terms in by_channel.items())


def between_vehicle_part(params: dict[str, float]) -> dict[str, float]:
    """The parameters of a discovered term whose features act between vehicles (sums over sources)."""
    return {k: v for k, v in params.items() if parse_term_key(k)[1] not in TARGET_ONLY_FEATURES}
