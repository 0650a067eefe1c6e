"""The discovery benchmark's ceiling (:mod:`bench_discovery`): would the EXACT hidden effect pass identify's
held-out test on a draw's train flights? A miss where it would not is a set whose flights cannot decide the
effect (too few flights, too little exposure, a test geometry the train flights never hold), not a search
that missed it; a miss where it would is the search's.

:func:`oracle_test` fits the hidden effect's exact shape (:func:`discovery_world.hidden_wrench` at unit
amplitude: ONE coefficient, the amplitude) beside a thrust scale per affected vehicle (the nuisance column
identify always refits, :mod:`proxplan.identify.priors`) to the residual of the CLEAN twin's final model on
the set with the effect (so everything but the effect is modelled as identify models it without the
effect), on the affected vehicles' channels (F_z, and roll/pitch/yaw torque for an effect with a torque),
each in units of that vehicle's clean twin test error in that channel. Each train flight is held out in
turn (a fit on the others); its gain and the energy of the change go to identify's own
:func:`proxplan.identify.heldout_select.ratio_test` with m = 1 (one hypothesis, no search: the most lenient
form of the test, so a ceiling). It ignores what identify adds (the in-fold selection mask, the Bonferroni
count over the stable candidates, the measurement's smoothing of the wrench), each of which can only make
the real test stricter.

A MIX (two hidden parts, :func:`discovery_world.draw_effect`) is fitted as the generator made it, one coefficient
for the sum; that test is carried by whichever part holds more of the train flights' error, and passes where the
other part cannot be decided at all (draw 37004: the mix passes at t = 24.9 on six flights while its kernel part
lies on one flight, where it disagrees with the others). Identify can only find a mix part by part (its terms
have coefficients of their own), and a mix is found only if every part is. So :func:`oracle_test` also tests
each part given the others (:func:`part_tests`: the part's column tested, the other parts' columns fitted beside
it like the thrust scales), and ``each_part_passed`` says whether every part passes: the ceiling for a mix.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from typing import Any

import numpy as np
from discovery_world import DT_S, SetSpec, flight_inputs, hidden_wrench


def _flight_index(flight: str) -> int:
    """The generator's flight number k of a flight named ``f<k>`` (:func:`discovery_world.make_set`)."""
    return int(flight.lstrip("f"))


def oracle_columns(spec: SetSpec, unit: Any, with_torque: bool, effect: Mapping[str, Any] | None = None) -> np.ndarray:
    """(N, C) the exact hidden wrench at unit amplitude on ``unit``'s samples (its own clock, s): F_z (N), and
    with ``with_torque`` the torque (3 columns, N m), world frame; of ``effect`` (a description of
    :func:`discovery_world.draw_effect`, default the set's own, ``spec.effect``)."""
    inputs = flight_inputs(spec, _flight_index(unit.flight))[unit.name]
    force, torque = hidden_wrench(dict(spec.effect if effect is None else effect), inputs)
    t_grid = np.arange(0.0, spec.duration_s, DT_S)
    cols = [force[:, 2]] + ([torque[:, 0], torque[:, 1], torque[:, 2]] if with_torque else [])
    return np.column_stack([np.interp(unit.t_s, t_grid, c) for c in cols])


def oracle_test(
    spec: SetSpec,
    hidden_units: Sequence[Any],
    clean_model: Any,
    affected: Sequence[str],
    clean_error: Mapping[str, Sequence[float]],
    with_torque: bool,
    exposed: Collection[str],
) -> dict[str, Any]:
    """The held-out test of the exact effect on the train flights (module docstring). ``hidden_units``: the
    identify result's units of the set with the effect; ``clean_model``: the clean twin's final model;
    ``clean_error``: per vehicle, its clean twin's test RMSE per channel (F_z in N, then the torque norm in N m:
    each channel's unit here); ``exposed``: the train flights (names) that hold the effect, the only ones judged
    (as identify judges a candidate only where it acts; the unit of ``bench_discovery._flights_holding``:
    the effect's RMS there at least an affected vehicle's clean test error). Returns :func:`heldout_oracle`'s, and
    for a mix ``parts`` (each part's :func:`part_tests` entry) and ``each_part_passed`` (module docstring)."""
    from proxplan.identify.data import predict

    rows: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}  # train flight -> (X, y) per affected vehicle
    names = sorted(affected)
    parts = list(spec.effect["parts"]) if spec.effect.get("family") == "mix" else []
    for u in hidden_units:
        if u.split != "train" or u.name not in names or not len(u):
            continue
        force, torque = predict(u, clean_model)
        fz_unit, tq_unit = (max(float(x), 1e-12) for x in clean_error[u.name])
        meas = [u.force_N[:, 2] - force[:, 2]] + (list((u.torque_Nm - torque).T) if with_torque else [])
        scale = np.array([fz_unit] + ([tq_unit] * 3 if with_torque else []))
        shape = oracle_columns(spec, u, with_torque) / scale
        y = (np.column_stack(meas) / scale).ravel()
        # a thrust scale per affected vehicle: its column is the logged thrust on F_z, 0 on the torques
        x_thr = np.zeros((len(y), len(names)))
        x_thr[:: shape.shape[1], names.index(u.name)] = u.thrust_z_N / fz_unit
        # each part's own column (a mix), then the whole effect's, then the thrust scales
        x_parts = [(oracle_columns(spec, u, with_torque, p) / scale).ravel() for p in parts]
        rows.setdefault(u.flight, []).append((np.column_stack([shape.ravel(), x_thr, *x_parts]), y))
    stacked = {f: (np.vstack([x for x, _ in r]), np.concatenate([y for _, y in r])) for f, r in rows.items()}
    n_nuisance = len(names)
    out = heldout_oracle({f: (x[:, : 1 + n_nuisance], y) for f, (x, y) in stacked.items()}, exposed)
    if parts:
        split = {f: (x[:, 1 + n_nuisance :], x[:, 1 : 1 + n_nuisance], y) for f, (x, y) in stacked.items()}
        out["parts"] = part_tests(split, exposed)
        out["each_part_passed"] = bool(out["passed"]) and all(p["passed"] for p in out["parts"])
    return out


def part_tests(
    stacked: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]], exposed: Collection[str]
) -> list[dict[str, Any]]:
    """The held-out test of each part of a mix given the others: ``stacked`` (flight -> (parts (n, P), nuisance
    (n, k), y (n,)), noise units); for part j, :func:`heldout_oracle` with column 0 that part's and the other parts'
    columns fitted beside the ``nuisance`` ones (each part then has a coefficient of its own, as identify's terms
    do). One entry per part (P)."""
    n_parts = next(iter(stacked.values()))[0].shape[1] if stacked else 0
    out = []
    for j in range(n_parts):
        others = [k for k in range(n_parts) if k != j]
        out.append(heldout_oracle(
            {f: (np.column_stack([p[:, j], p[:, others], nuisance]), y) for f, (p, nuisance, y) in stacked.items()},
            exposed))  # fmt: skip
    return out


def heldout_oracle(stacked: Mapping[str, tuple[np.ndarray, np.ndarray]], exposed: Collection[str]) -> dict[str, Any]:
    """Each flight of ``stacked`` (flight -> (X (n, 1 + k), y (n,)), noise units; column 0 the effect's shape, the
    others nuisance columns) held out in turn: the fit on the other flights with column 0 and without it, the
    held-out gain (squared error removed), the energy of the change and the squared error without, judged on the
    ``exposed`` flights by :func:`proxplan.identify.heldout_select.ratio_test` with m = 1. Returns the test's JSON
    (t, the multiple required, passed, the share of the held-out error removed), ``n_flights`` judged and the
    fitted column-0 coefficient per held-out flight; ``passed`` False with a ``note`` where fewer than two exposed
    flights can be judged (no standard error, no test)."""
    from proxplan.identify.heldout_select import ratio_test

    flights = sorted(stacked)
    judged = [f for f in flights if f in exposed]
    if len(flights) < 2 or len(judged) < 2:
        return {"passed": False, "n_flights": len(judged), "note": "fewer than two train flights hold the effect"}
    gains, energies, sse, amplitudes = [], [], [], []
    for held in judged:
        x_fit = np.vstack([stacked[f][0] for f in flights if f != held])
        y_fit = np.concatenate([stacked[f][1] for f in flights if f != held])
        beta0 = np.linalg.lstsq(x_fit[:, 1:], y_fit, rcond=None)[0]  # without the effect: the nuisance alone
        beta1 = np.linalg.lstsq(x_fit, y_fit, rcond=None)[0]
        x, y = stacked[held]
        r0 = y - x[:, 1:] @ beta0
        d = x @ beta1 - x[:, 1:] @ beta0
        gains.append(float(r0 @ r0 - (r0 - d) @ (r0 - d)))
        energies.append(float(d @ d))
        sse.append(float(r0 @ r0))
        amplitudes.append(float(beta1[0]))
    test = ratio_test(np.array(gains), np.array(energies), np.array(sse), 1)
    return test.to_json() | {"n_flights": len(judged), "amplitude_per_heldout_flight": amplitudes}
