"""Counting lines: direction convention, once per track per line, flicker, segment extent."""

import numpy as np

from vtrack.analytics.lines import LineCounter


def _feed(counter, tid, pts, start=1):
    """Feed a path; returns the crossings it completed."""
    out = []
    for k, p in enumerate(pts):
        out += counter.add(tid, start + k, (start + k) / 25, np.array(p, float))
    return out


def test_moving_down_across_horizontal_line_is_forward():
    c = LineCounter([[0, 100, 640, 100]])
    crossings = _feed(c, 1, [(50, 90), (50, 95), (50, 105)])
    assert c.counts()[0] == {"line": [0.0, 100.0, 640.0, 100.0], "forward": 1, "backward": 0,
                             "total": 1}
    assert crossings[0].frame == 3 and crossings[0].direction == "forward"


def test_moving_up_is_backward():
    c = LineCounter([[0, 100, 640, 100]])
    _feed(c, 1, [(50, 110), (50, 90)])
    assert c.counts()[0]["backward"] == 1


def test_flicker_on_the_line_counts_once_in_first_direction():
    c = LineCounter([[0, 100, 640, 100]])
    _feed(c, 7, [(50, 98), (50, 101), (50, 99), (50, 102), (50, 99.5), (50, 103)])
    assert c.counts()[0]["total"] == 1 and c.counts()[0]["forward"] == 1


def test_touching_the_line_and_turning_back_does_not_count():
    c = LineCounter([[0, 100, 640, 100]])
    _feed(c, 1, [(50, 95), (50, 100), (50, 96)])
    assert c.counts()[0]["total"] == 0


def test_passing_beside_the_segment_does_not_count():
    c = LineCounter([[0, 100, 200, 100]])
    _feed(c, 1, [(300, 90), (300, 110)])
    assert c.counts()[0]["total"] == 0


def test_each_track_and_line_counted_separately():
    c = LineCounter([[0, 100, 640, 100], [0, 200, 640, 200]])
    crossings = _feed(c, 1, [(10, 50), (10, 150), (10, 250)])
    crossings += _feed(c, 2, [(20, 250), (20, 150), (20, 50)])
    counts = c.counts()
    assert counts[0]["forward"] == 1 and counts[0]["backward"] == 1
    assert counts[1]["forward"] == 1 and counts[1]["backward"] == 1
    assert len(crossings) == 4


def test_a_forgotten_track_leaves_no_state_and_keeps_the_tallies():
    """Memory stays flat: a finished track's path state goes; the counts stay."""
    c = LineCounter([[0, 100, 640, 100]])
    _feed(c, 1, [(50, 90), (50, 110)])
    c.forget(1)
    assert not c._last and not c._counted
    assert c.counts()[0]["forward"] == 1
