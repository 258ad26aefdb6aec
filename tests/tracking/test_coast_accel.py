"""`coast_accel_rate`: a coasting track's acceleration decays (Singer's Markov
acceleration, models.singer_transition) instead of being held for the whole coast."""

from __future__ import annotations

import numpy as np

from vtrack.app.config import AppConfig
from vtrack.boxes import centre
from vtrack.estimation.models import ConstantAcceleration, singer_transition
from vtrack.tracking.tracker import Tracker

W, H, FPS = 640, 360, 25.0


def test_singer_transition_limits_and_semigroup() -> None:
    dt = 0.04
    assert np.allclose(singer_transition(dt, 0.0), ConstantAcceleration(1.0).transition(dt))
    assert np.allclose(singer_transition(dt, 1e-6), ConstantAcceleration(1.0).transition(dt))
    cv = singer_transition(dt, np.inf)
    assert np.allclose(cv[:4, :4], ConstantAcceleration(1.0).transition(dt)[:4, :4])
    assert np.allclose(cv[:, 4:], 0.0)
    assert np.allclose(singer_transition(dt, 1e6)[:, 4:], 0.0, atol=1e-5)
    # a Markov process: two steps are one step over their sum
    assert np.allclose(singer_transition(0.03, 3.0) @ singer_transition(0.05, 3.0),
                       singer_transition(0.08, 3.0))


def _coasted_velocity(rate: float, coast: int = 20) -> np.ndarray:
    """A 50 px vehicle braking (10 px/frame slowing by 0.3 px/frame^2) for 20 frames,
    then no detection for `coast` frames: the track's x velocity (px/s) on each."""
    cfg = AppConfig().tracker
    cfg.coast_accel_rate = rate
    tracker = Tracker(cfg, W, H, FPS)
    for n in range(20):
        box = np.array([[20.0 + 10 * n - 0.15 * n**2, 150.0, 50.0, 50.0]])
        out = tracker.step(n + 1, n / FPS, centre(box), box)
    assert len(out.ids) == 1, "the vehicle is confirmed"
    vx = []
    for n in range(20, 20 + coast):
        out = tracker.step(n + 1, n / FPS, np.zeros((0, 2)), np.zeros((0, 4)))
        assert len(out.ids) == 1 and out.coasted[0]
        vx.append(tracker.tracks.x[0, 2])
    return np.array(vx)


def test_constant_acceleration_turns_a_braking_vehicle_back() -> None:
    assert _coasted_velocity(0.0)[-1] < 0      # the held braking reverses the prediction


def test_decaying_acceleration_keeps_it_going_forward() -> None:
    vx = _coasted_velocity(5.0)
    assert np.all(vx > 0)
    assert vx[-1] > 0.5 * vx[0]                 # the braking fades within a few 1/rate
    assert np.ptp(_coasted_velocity(np.inf)[1:]) < 1e-9   # rate inf: constant velocity
