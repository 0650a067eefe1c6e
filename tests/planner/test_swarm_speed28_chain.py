"""Round 28B (issue 37): the chain's search asks a move's departures only for the arrivals that can
still improve it (:func:`proxplan.planner.swarm.chain._live_arrivals`), and builds each move once per
problem (:func:`proxplan.planner.swarm.chain._flown`). Both exact: whole swarm plans equal, track for
track, with the reference in their place (every safe arrival asked; every move built afresh in every
search), and the work they save is real (fewer departure queries, fewer moves built)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import chain
from proxplan.planner.swarm.memo import Memo
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.plan import swarm_timed

_live = chain._live_arrivals
_flown = chain._flown


def _every_arrival(best, j, runs, starts, a_lo, a_hi, T):
    return a_lo, a_hi  # the reference: every safe arrival asked


def _afresh(problem, limits, W, k, j, run, dev):
    """The move built in every search (a memo that keeps nothing), the problem's static answers as before."""
    fresh = SimpleNamespace(static_memo=Memo(0), static_free=problem.static_free, segment_free=problem.segment_free)
    return _flown(fresh, limits, W, k, j, run, dev)


def _plan(layout: str, n: int, monkeypatch, **patches):
    """swarm_timed's plan of ``layout``-``n`` with ``patches`` (name in chain -> function), and the
    number of departure queries asked and of moves built."""
    counts = {"queries": 0, "moves": 0}
    ask = Occupancy.forbidden_departures

    def counted_ask(self, *a, **kw):
        counts["queries"] += 1
        return ask(self, *a, **kw)

    def counted(cls):
        def make(*a, **kw):
            counts["moves"] += 1
            return cls(*a, **kw)

        return make

    with monkeypatch.context() as m:
        for name, fn in patches.items():
            m.setattr(chain, name, fn)
        m.setattr(Occupancy, "forbidden_departures", counted_ask)
        m.setattr(chain, "LineMove", counted(chain.LineMove))
        m.setattr(chain, "RunMove", counted(chain.RunMove))
        timed, info = swarm_timed(scenario_from_dict(LAYOUTS[layout](n), label="test"))
    return timed, info, counts


def _same(a, b) -> None:
    (ta, ia), (tb, ib) = a, b
    assert ia.stage == ib.stage and ia.makespan_s == ib.makespan_s
    assert ta.keys() == tb.keys()
    for name in ta:
        np.testing.assert_array_equal(ta[name].knot_t_s, tb[name].knot_t_s)
        t = np.arange(0.0, ta[name].duration_s + 0.1, 0.01)
        np.testing.assert_array_equal(ta[name].sample(t)[0], tb[name].sample(t)[0])


@pytest.mark.parametrize("layout,n", [("corridor", 12), ("grid", 16)])
def test_live_arrivals_and_moves_once_plan_the_same(layout, n, monkeypatch):
    got, info, counts = _plan(layout, n, monkeypatch)
    ref, ref_info, ref_counts = _plan(layout, n, monkeypatch, _live_arrivals=_every_arrival, _flown=_afresh)
    _same((got, info), (ref, ref_info))
    assert counts["queries"] < ref_counts["queries"]
    assert counts["moves"] < ref_counts["moves"]


def test_live_arrivals_drops_only_intervals_that_cannot_gain():
    runs = [(0, 10), (20, 30), (40, 50)]
    starts = np.array([0, 20, 40])
    T = 100
    # nothing found yet: every arrival asked
    assert _live({}, 3, runs, starts, 5, 45, T) == (5, 45)
    # the first interval has an arrival at 5 (no later than 5): from the second interval's first step
    assert _live({(3, 0): 5}, 3, runs, starts, 5, 45, T) == (20, 45)
    # one at 6 in it: an arrival at 5 would still gain
    assert _live({(3, 0): 6}, 3, runs, starts, 5, 45, T) == (5, 45)
    # the last interval holds 40 (its first step): up to the second interval's last step
    assert _live({(3, 2): 40}, 3, runs, starts, 5, 45, T) == (5, 29)
    # every interval reached has its earliest possible arrival: nothing to ask
    assert _live({(3, 0): 5, (3, 1): 20, (3, 2): 40}, 3, runs, starts, 5, 45, T) is None
    # another waypoint's arrivals do not count
    assert _live({(4, 0): 0, (4, 1): 0, (4, 2): 0}, 3, runs, starts, 5, 45, T) == (5, 45)
