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
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from typing import Any

import numpy as np
from discovery_world import DT_S, SetSpec, flight_inputs, hidden_wrench


def _flight_index(flight: str) -> int:
    """The generator's flight number k of a flight named ``f<k>`` (:func:`discovery_world.make_set`)."""
    return int(flight.lstrip("f"))


def oracle_columns(spec: SetSpec, unit: Any, with_torque: bool) -> np.ndarray:
    """(N, C) the exact hidden wrench at unit amplitude on ``unit``'s samples (its own clock, s): F_z (N), and
    with ``with_torque`` the torque (3 columns, N m), world frame."""
    inputs = flight_inputs(spec, _flight_index(unit.flight))[unit.name]
    force, torque = hidden_wrench(spec.effect, inputs)
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
    the effect's RMS there at least an affected vehicle's clean test error). Returns :func:`heldout_oracle`'s."""
    from proxplan.identify.data import predict

    rows: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}  # train flight -> (X, y) per affected vehicle
    names = sorted(affected)
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
        rows.setdefault(u.flight, []).append((np.column_stack([shape.ravel(), x_thr]), y))
    stacked = {f: (np.vstack([x for x, _ in r]), np.concatenate([y for _, y in r])) for f, r in rows.items()}
    return heldout_oracle(stacked, exposed)


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
