"""Shipped undamped-zone tables (proxplan.planner.swarm.zone_store, issue 37 round 19A): a plan reads
the table of its facts instead of searching it, and the keep-outs are the same as with the search.
When a test here fails after a change of the physics, the loop model or the search, ship the tables
again: ``python -m proxplan.planner.swarm.keepout`` (about 20 s)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from proxplan.costmaps import effects_key
from proxplan.physics import BUILTIN_VEHICLES
from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import keepout, zone_store
from proxplan.planner.swarm.problem import GROWTH_M

BENCH_TYPES = ("crazyflie-2.1", "crazyflie-parrot", "small-quad")  # the benchmarks' three types


def _facts(source, target, level=0.1):
    return keepout.zone_facts(
        source, target, level=level, rule="conservative", field_form=None, effects=effects_key(())
    )


def _keepouts(scenario, vehicles):
    fx = effects_key(getattr(scenario, "effects", ()))
    return {
        (a.name, b.name): keepout.keepout_for(
            a, b, limits=scenario.limits, field_form=scenario.field_form, effects=fx, sample_m=GROWTH_M
        )
        for a in vehicles
        for b in vehicles
    }


def test_keepouts_with_the_shipped_tables_equal_those_searched(monkeypatch):
    """The nine ordered pairs of the benchmarks' types at the layouts' level: every table is shipped
    and equal to the search's, and so are the four tables of each keep-out built on them."""
    scenario = scenario_from_dict(grid_reshuffle(9, types=list(BENCH_TYPES)), label="test scenario")
    vehicles = [BUILTIN_VEHICLES[n] for n in BENCH_TYPES]
    for a in vehicles:
        for b in vehicles:
            key = zone_store.facts_key(_facts(a, b, scenario.limits.authority_fraction))
            assert zone_store.shipped_zone(key) is not None, (a.name, b.name, "not shipped: ship again")
    keepout.undamped_radius_m.cache_clear()
    shipped = _keepouts(scenario, vehicles)
    keepout.undamped_radius_m.cache_clear()
    monkeypatch.setattr(zone_store, "shipped_zone", lambda key, path=None: None)  # search every table
    try:
        searched = _keepouts(scenario, vehicles)
    finally:
        keepout.undamped_radius_m.cache_clear()
    assert any(ko.a_on_b.size > 0 and ko.a_on_b.max() > 0 for ko in searched.values())
    for pair, ko in searched.items():
        for field in ("a_on_b", "b_on_a", "a_on_b_rest", "b_on_a_rest"):
            assert np.array_equal(getattr(shipped[pair], field), getattr(ko, field)), (pair, field)


def test_another_fact_misses_the_shipped_table():
    """A fact the loop depends on but the cost maps do not (the motor's time constant), another level
    or another search step gives another key, with no shipped table: the table is searched."""
    cf, sq = BUILTIN_VEHICLES["crazyflie-2.1"], BUILTIN_VEHICLES["small-quad"]
    base = zone_store.facts_key(_facts(cf, sq))
    assert zone_store.shipped_zone(base) is not None
    slower = dataclasses.replace(sq, motor_time_constant_s=sq.motor_time_constant_s * 1.5)
    for facts in (
        _facts(cf, slower),
        _facts(cf, sq, level=0.2),
        {**_facts(cf, sq), "constants": [0.01, 0.02, 8, [0.0]]},
    ):
        key = zone_store.facts_key(facts)
        assert key != base
        assert zone_store.shipped_zone(key) is None


def test_the_code_digest_follows_the_search_source():
    assert zone_store.code_digest("a") != zone_store.code_digest("b")


@pytest.mark.slow
def test_every_shipped_table_is_current():
    """Every table the file ships (built-in pairs, both shipped levels) equals the search's (~20 s)."""
    for request in keepout.default_zone_requests():
        key = zone_store.facts_key(keepout.zone_facts(**request))
        table = zone_store.shipped_zone(key)
        assert table is not None, (request["source"].name, request["target"].name, request["level"])
        assert np.array_equal(table, keepout.search_undamped_radius_m(**request))
