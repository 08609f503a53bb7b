"""The closest approach to each limit tallied chunk by chunk (:class:`~prs3_post.post.limits.LimitTally`)
equals the one of the whole report: the smallest margin per limit, its value and its first row."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal

from prs3_post.kinematics import unit_axes
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import load_machine
from prs3_post.post.limits import LimitTally, check_limits


def _report(rows: int, seed: int = 7):
    machine = load_machine("patel2020")
    rng = np.random.default_rng(seed)
    tip = np.column_stack([rng.uniform(-60, 60, rows), rng.uniform(-60, 60, rows), rng.uniform(-700, -660, rows)])
    axis = unit_axes(tip, np.column_stack([rng.uniform(-0.3, 0.3, (rows, 2)), np.ones(rows)]))
    ik = kinematics_of(machine).inverse(tip, axis)
    return check_limits(machine, ik, axis)


def test_a_tally_folded_in_chunks_is_the_whole_report_s_minimum() -> None:
    report = _report(1000)
    whole = LimitTally.of(report)
    best = np.argmin(report.margin, axis=0)
    assert_array_equal(whole.row, best)
    assert_allclose(whole.margin, report.margin[best, np.arange(len(best))], atol=0)
    assert_allclose(whole.value, report.value[best, np.arange(len(best))], atol=0)
    chunked = LimitTally()
    for start in range(0, 1000, 137):
        part = slice(start, min(start + 137, 1000))
        chunked.fold(type(report)(names=report.names, units=report.units, low=report.low, high=report.high,
                                  value=report.value[part], margin=report.margin[part], ok=report.ok[part]))
    assert chunked.rows == 1000
    assert_array_equal(chunked.row, whole.row)
    assert_allclose(chunked.margin, whole.margin, atol=0)
    pieces = LimitTally()                               # two pieces joined: the second's rows come after
    pieces.merged(LimitTally.of(_report(10, seed=1)), 0)
    pieces.merged(whole, 10)
    both = np.minimum(LimitTally.of(_report(10, seed=1)).margin, whole.margin)
    assert_allclose(pieces.margin, both, atol=0)
    assert pieces.rows == 1010
    from_whole = pieces.margin == whole.margin
    assert_array_equal(pieces.row[from_whole & (pieces.margin < LimitTally.of(_report(10, seed=1)).margin)],
                       whole.row[from_whole & (pieces.margin < LimitTally.of(_report(10, seed=1)).margin)] + 10)


def test_an_empty_tally_has_no_limits() -> None:
    tally = LimitTally()
    tally.merged(LimitTally(), 5)
    assert (tally.names, tally.rows, len(tally.margin)) == ((), 5, 0)
