"""The discovery benchmark's ceiling (benchmarks/discovery_oracle.heldout_oracle): the held-out test of an exact
shape passes where the flights hold it and cannot pass where fewer than two of them do."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from discovery_oracle import heldout_oracle  # noqa: E402


def _flights(amplitude: float, n_flights: int, seed: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Flights of 400 samples: y = amplitude x + 0.05 thrust + unit noise, x a smooth shape, thrust near 1."""
    rng = np.random.default_rng(seed)
    out = {}
    for k in range(n_flights):
        t = np.linspace(0.0, 20.0, 400)
        x = np.sin(2 * np.pi * rng.uniform(0.1, 0.4) * t + rng.uniform(0, 6)) + 0.5 * rng.standard_normal()
        thrust = 1.0 + 0.1 * rng.standard_normal(t.size)
        y = amplitude * x + 0.05 * thrust + rng.standard_normal(t.size)
        out[f"f{k}"] = (np.column_stack([x, thrust]), y)
    return out


def test_an_exact_shape_passes_and_its_amplitude_is_found() -> None:
    flights = _flights(amplitude=1.0, n_flights=3, seed=1)
    got = heldout_oracle(flights, exposed=set(flights))
    assert got["passed"] and got["n_flights"] == 3
    assert np.allclose(
        got["amplitude_per_heldout_flight"], 1.0, atol=0.25
    )  # deviations seen over seeds 0-4: up to 0.12


def test_no_effect_does_not_pass() -> None:
    passed = [heldout_oracle(f, exposed=set(f))["passed"] for f in (_flights(0.0, 3, s) for s in range(20))]
    assert sum(passed) <= 3  # a one-sided 5 % test: about 1 in 20; 3 or fewer with probability 0.98


def test_fewer_than_two_exposed_flights_is_no_test() -> None:
    flights = _flights(amplitude=0.5, n_flights=3, seed=2)
    got = heldout_oracle(flights, exposed={"f1"})
    assert not got["passed"] and got["n_flights"] == 1 and "fewer than two" in got["note"]


def _mix_flights(seed: int) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Four flights of 400 samples holding a mix y = a + 0.2 b + 0.05 thrust + unit noise: part a (a speed, say) on
    every flight, part b (a kernel beside a neighbour) only on flight f0; (parts (n, 2), nuisance (n, 1), y)."""
    rng = np.random.default_rng(seed)
    out = {}
    for k in range(4):
        t = np.linspace(0.0, 20.0, 400)
        a = np.sin(2 * np.pi * rng.uniform(0.1, 0.4) * t + rng.uniform(0, 6))
        b = np.exp(-(((t - 10.0) / 3.0) ** 2)) if k == 0 else np.zeros(t.size)
        thrust = 1.0 + 0.1 * rng.standard_normal(t.size)
        y = a + 0.2 * b + 0.05 * thrust + rng.standard_normal(t.size)
        out[f"f{k}"] = (np.column_stack([a, b]), thrust[:, None], y)
    return out


def test_a_mix_part_on_one_flight_is_not_decidable_though_the_mix_passes() -> None:
    from discovery_oracle import part_tests

    flights = _mix_flights(seed=3)
    mix = heldout_oracle(
        {f: (np.column_stack([p.sum(axis=1), n]), y) for f, (p, n, y) in flights.items()}, set(flights)
    )
    parts = part_tests(flights, set(flights))
    assert mix["passed"]  # one coefficient for the sum: carried by part a, on every flight
    assert parts[0]["passed"]  # part a given part b
    assert not parts[1]["passed"]  # part b lies on f0 alone: no flight-level test can decide it
