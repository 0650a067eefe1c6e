"""A kept term's coefficient split by target vehicle type (:mod:`proxplan.identify.type_split`): where one shared
coefficient does not describe every target type (bench draws 29001 and 30001: a term right for one type, 2-3.6x
wrong for the other), each type gets its own, saved as ``"<key>@<type>"`` and applied to that type only; where
one coefficient does describe them, the term stays shared."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from proxplan.identify.data import IdentifyOptions, errors
from proxplan.physics import (
    BUILTIN_VEHICLES,
    DISCOVERED_PREFIX,
    Effect,
    EffectInputs,
    SourceSample,
    effect_wrench,
    feature_matrix,
    parse_term_key,
    term_formula,
    term_type,
    typed_key,
    untyped_key,
)
from tests.identify.synthetic_runs import identify_flights, kept_terms, torque_rmse_on_test_Nm

SOURCE, SMALL, PARROT = "large-quad", "small-quad", "crazyflie-parrot"
TYPES = {"a": SOURCE, "b": SMALL, "c": PARROT}
FEATURE = "above_jet_1"
"""The hidden force's shape: the jet kernel of the sources above (:mod:`proxplan.physics.features`)."""
KEY = f"force_z_N*W*{FEATURE}"
"""The term key of that shape."""
SHARED = {SMALL: 0.2, PARROT: 0.2}
"""Per target type, the hidden force per unit of the target's weight (-): one coefficient describes both."""
PER_TYPE = {SMALL: 0.2, PARROT: 0.06}
"""The same, 3.3x apart (the mismatch of bench draw 30001 was 2.75x): no one coefficient describes both."""
OPTIONS = IdentifyOptions(max_fit_samples=4000, max_eval_samples=3000)


def _hidden(per_type: dict[str, float]):
    def wrench(inputs: EffectInputs) -> tuple[np.ndarray, np.ndarray]:
        """F_z = -k(type) W x the jet kernel of the sources above (``FEATURE``, a feature of the dictionary: the
        split is what is judged here, not the search for a shape)."""
        force, torque = np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))
        zero = [(np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))) for _ in inputs.sources]
        jet = feature_matrix(inputs, zero, [FEATURE])[:, 0]
        force[:, 2] = -per_type.get(inputs.target.name, 0.0) * inputs.target.weight_N * jet
        return force, torque

    return wrench


def _trajectories(t: np.ndarray, phase: float) -> dict[str, np.ndarray]:
    """'a' (large) at 1.5 m sweeps across y = -0.4 .. 0.4 m; 'b' (small) and 'c' (Parrot) 0.45-0.85 m below it,
    0.7 m apart in y, each passing under 'a' as it sweeps, never under each other."""
    a = np.column_stack([0.15 * np.sin(2 * np.pi * t / 5.0 + phase), 0.4 * np.sin(2 * np.pi * t / 7.0 + phase),
                         1.5 + 0 * t])  # fmt: skip
    b = np.column_stack([0.1 * np.cos(2 * np.pi * t / 6.0 + 2 * phase), -0.35 + 0.08 * np.sin(2 * np.pi * t / 4.0),
                         0.85 - 0.2 * np.sin(2 * np.pi * t / 5.0 + phase)])  # fmt: skip
    c = np.column_stack([0.1 * np.sin(2 * np.pi * t / 6.5 + phase), 0.35 + 0.08 * np.cos(2 * np.pi * t / 4.5),
                         0.85 - 0.2 * np.cos(2 * np.pi * t / 5.5 + 2 * phase)])  # fmt: skip
    return {"a": a, "b": b, "c": c}


def _run(tmp: Path, per_type: dict[str, float] | None):
    hidden = None if per_type is None else _hidden(per_type)
    return identify_flights(tmp, TYPES, lambda t, k: _trajectories(t, 0.7 * k), hidden, options=OPTIONS,
                            n_flights=6, n_test=1)  # fmt: skip


def test_typed_keys_parse_and_act_on_their_type_only() -> None:
    key = typed_key(KEY, PARROT)
    assert key == f"{KEY}@{PARROT}" and term_type(key) == PARROT and untyped_key(key) == KEY
    assert parse_term_key(key) == parse_term_key(KEY) and term_type(KEY) is None
    assert "[on crazyflie-parrot]" in term_formula({key: -0.1})
    with pytest.raises(ValueError, match="vehicle type"):
        parse_term_key(KEY + "@")
    with pytest.raises(ValueError, match="already names"):
        typed_key(key, SMALL)
    src = BUILTIN_VEHICLES[SOURCE]
    n = 5
    offsets = np.column_stack([np.zeros(n), np.linspace(-0.2, 0.2, n), -0.5 * np.ones(n)])  # 0.5 m below

    def inputs(target: str) -> EffectInputs:
        return EffectInputs(BUILTIN_VEHICLES[target], np.full(n, 1.0), np.zeros((n, 3)),
                            (SourceSample(src, offsets, np.zeros((n, 3))),))  # fmt: skip

    shared = Effect(DISCOVERED_PREFIX + "t", {KEY: -0.1})
    typed = Effect(DISCOVERED_PREFIX + "t", {typed_key(KEY, PARROT): -0.1})
    on_parrot = effect_wrench(typed, inputs(PARROT))[0][:, 2]
    np.testing.assert_array_equal(on_parrot, effect_wrench(shared, inputs(PARROT))[0][:, 2])
    assert np.all(on_parrot < 0.0)
    assert not np.any(effect_wrench(typed, inputs(SMALL))[0])


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory):
    return _run(tmp_path_factory.mktemp("split_clean"), None)


def _test_rmse(result, model, vehicle: str) -> float:
    return errors([u for u in result.units if u.split == "test" and u.name == vehicle], model).rmse_fz_N


@pytest.mark.slow
def test_a_term_whose_coefficient_differs_by_target_type_is_split(tmp_path: Path, clean) -> None:
    """The hidden force per unit of the target's weight is 3.3x larger on the small quad than on the Parrot: the
    kept term is split (its per-type form beat the one-coefficient form in the forward pass), each type's coefficient near its own, and each target's test F_z within 1.3x of the
    clean twin's (a shared coefficient would sit between the two and miss both)."""
    result = _run(tmp_path, PER_TYPE)
    kept = kept_terms(result)
    coef = {term_type(k): v for k, v in kept.items() if untyped_key(k) == KEY}
    assert set(coef) == {SMALL, PARROT} and all(term_type(k) for k in kept if untyped_key(k) == KEY), kept
    for t, value in coef.items():
        assert abs(-value / PER_TYPE[t] - 1.0) < 0.2, coef
    split = next(e["type_split"] for e in result.discovered if e["selected"] and e["target_type"] is not None)
    assert split["form"] == "per target type" and split["types"] == [SMALL, PARROT], split
    assert split["test_per_type"]["passed"], split
    for vehicle in ("b", "c"):
        after = _test_rmse(result, result.final_model, vehicle)
        assert after <= 1.3 * _test_rmse(clean, clean.final_model, vehicle), (vehicle, after, kept)


@pytest.mark.slow
def test_a_term_one_coefficient_describes_stays_shared(tmp_path: Path, clean) -> None:
    """The same force with one coefficient for both types: the term is kept shared (its split tested and refused),
    its coefficient near the truth, and each target's test F_z within 1.3x of the clean twin's."""
    result = _run(tmp_path, SHARED)
    kept = kept_terms(result)
    assert KEY in kept and not any(term_type(k) for k in kept), kept
    assert abs(-kept[KEY] / SHARED[SMALL] - 1.0) < 0.2, kept
    forms = [e["type_split"] for e in result.discovered if e["selected"]]
    assert forms and all(f is not None and f["form"] == "one coefficient" for f in forms), forms
    for vehicle in ("b", "c"):
        after = _test_rmse(result, result.final_model, vehicle)
        assert after <= 1.3 * _test_rmse(clean, clean.final_model, vehicle), (vehicle, after, kept)


SWAP = {"a": SMALL, "b": SOURCE}
ROLL_C = 0.02
"""The hidden roll torque's amplitude per unit of the target's weight times the SOURCE's size (-)."""


def _roll_from_above(inputs: EffectInputs) -> tuple[np.ndarray, np.ndarray]:
    """tau_x = 0.02 W_target L_source exp(-(r / L)^2 - dz / 4 L) y / L from a source above (L the source's size):
    scaled by the source's size, so per unit of the target's W L it is L_src / L_tgt (bench draw 31006's law)."""
    force, torque = np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))
    for src in inputs.sources:
        off = src.offsets_m
        dz, r = -off[:, 2], np.hypot(off[:, 0], off[:, 1])
        L = src.vehicle.size_m
        kernel = np.where(dz > 0, np.exp(-((r / L) ** 2) - dz / (4 * L)), 0.0)
        torque[:, 0] += ROLL_C * inputs.target.weight_N * kernel * off[:, 1]
    return force, torque


def _swapping(t: np.ndarray, phase: float, small_on_top: bool) -> dict[str, np.ndarray]:
    """One vehicle at 1.6 m, the other 0.4-0.7 m below it, swaying +-0.25-0.3 m across its axis; which one is on
    top alternates from flight to flight."""
    top = np.column_stack([0.1 * np.sin(2 * np.pi * t / 5.0 + phase), 0.1 * np.cos(2 * np.pi * t / 6.0 + phase),
                           1.6 + 0 * t])  # fmt: skip
    low = np.column_stack([top[:, 0] + 0.25 * np.sin(2 * np.pi * t / 4.0 + 2 * phase),
                           top[:, 1] + 0.3 * np.sin(2 * np.pi * t / 3.0 + phase),
                           1.6 - (0.55 + 0.15 * np.sin(2 * np.pi * t / 5.0 + phase))])  # fmt: skip
    return {"a": top, "b": low} if small_on_top else {"a": low, "b": top}


def _run_swapping(tmp: Path, hidden):
    return identify_flights(tmp, SWAP, lambda t, k: _swapping(t, 0.7 * k, k % 2 == 0), hidden, options=OPTIONS,
                            n_flights=7, n_test=2)  # fmt: skip


def test_a_torque_scaling_with_the_source_is_kept_in_its_lever_form(tmp_path: Path) -> None:
    """A roll torque from the vehicle above that scales with the SOURCE's size, a small and a large quad taking
    turns on top: per unit of the target's W L it is 7.95x larger on the small quad. One coefficient of the side
    axis cannot fit both (on 3b53525 the kept term left the small quad's test torque at 1.83x its clean twin's);
    one per target type can (each C L_src / L_tgt, 18b4938), and so can the side axis' lever form with ONE
    coefficient C (the force at its lever arm, :mod:`proxplan.identify.lever_form`), which has fewer columns and
    is kept (since round 37K): one coefficient for both types near C, and both vehicles' test torques within 1.3x
    of the clean twin's, which keeps nothing."""
    clean = _run_swapping(tmp_path / "clean", None)
    result = _run_swapping(tmp_path / "effect", _roll_from_above)
    assert not [e for e in clean.discovered if e["selected"]]
    kept = kept_terms(result)
    roll = {k: v for k, v in kept.items() if k.startswith("torque_x_Nm*W*above_")}
    assert len(roll) == 1 and all(term_type(k) is None and k.endswith("_yt_1") for k in roll), kept
    assert abs(next(iter(roll.values())) / ROLL_C - 1.0) < 0.3, kept

    for vehicle in SWAP:
        assert torque_rmse_on_test_Nm(result, vehicle) <= 1.3 * torque_rmse_on_test_Nm(clean, vehicle), (vehicle, kept)
