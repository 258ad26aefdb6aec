"""Per-frame tracker time at 10, 100 and 1000 simultaneous targets: vtrack's batched tracker
next to two plain per-track filterpy baselines on the same detections, measured in one run.

- vtrack: prediction, k-d-tree gating, per-group assignment, batched Joseph update, lifecycle.
- per-track tracker: what a plain tracker with one filterpy KalmanFilter object per vehicle
  does each frame (the SORT pattern): predict every object, one dense Mahalanobis cost matrix
  with gating, one scipy linear_sum_assignment over it, then per matched track its
  finite-difference measurement (seed 001 eqs. 24-26, R = D Sigma D') and update.
- filters only: just the predict + update calls of those objects, with the association and
  the measurements handed over for free (a lower bound for any per-track design).

Both baselines are checked to follow every target, so all three do the same job. Times are
medians over the second half of the frames: the steady state in which the targets' tracks
are established (all tracks starting in one frame is a transient a video never has).

    .venv/bin/python scripts/bench_tracker.py [--frames 40]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from vtrack.estimation.models import ConstantAcceleration
from vtrack.tracking.measurements import difference_operator, finite_difference_measurement
from vtrack.tracking.tracker import Tracker, TrackerConfig

FPS = 25.0
CFG = TrackerConfig()
BOX = 30.0   # px: every target's box is 30 x 30; the config's scale-free values in pixels
JERK = CFG.jerk * BOX**2                      # px^2/s^5
SIGMA = max(CFG.detection_sigma * BOX, 0.5)   # px


def _steady(times: list[float]) -> float:
    """Median per-frame time over the second half of the run."""
    return float(np.median(times[len(times) // 2:]))


def scenario(n: int, frames: int, seed: int = 0) -> tuple[np.ndarray, int, int]:
    """n targets on a grid, constant velocity with small acceleration; (frames, n, 2)."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    spacing = 150.0
    w = h = int(side * spacing + 400)
    start = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n]
    start = start * spacing + 100.0
    vel = rng.uniform(-40, 40, (n, 2))
    acc = rng.uniform(-5, 5, (n, 2))
    t = np.arange(frames)[:, None, None] / FPS
    pos = start + vel * t + 0.5 * acc * t**2 + rng.normal(0, 1.5, (frames, n, 2))
    return pos, w, h


def bench_vtrack(pos: np.ndarray, w: int, h: int) -> float:
    tr = Tracker(TrackerConfig(), w, h)
    boxes = np.zeros((pos.shape[1], 4))
    boxes[:, 2:] = BOX
    times = []
    for k, p in enumerate(pos):
        boxes[:, :2] = p - BOX / 2
        t0 = time.perf_counter()
        tr.step(k + 1, k / FPS, p, boxes)
        times.append(time.perf_counter() - t0)
    assert len(tr) == pos.shape[1], "every target should still be tracked"
    return _steady(times)


def _new_filter(p: np.ndarray):
    from filterpy.kalman import KalmanFilter

    kf = KalmanFilter(dim_x=6, dim_z=6)
    kf.H = np.eye(6)
    kf.x = np.array([p[0], p[1], 0, 0, 0, 0.0])
    kf.P = np.diag([SIGMA**2] * 2 + [(CFG.init_speed_sigma * BOX)**2] * 2
                   + [(CFG.init_accel_sigma * BOX)**2] * 2)
    return kf


class _Track:
    """One vehicle of the per-track baseline: its filter and its last three detections."""

    def __init__(self, p: np.ndarray, t: float) -> None:
        self.kf = _new_filter(p)
        self.points = [p]
        self.times = [t]

    def update(self, p: np.ndarray, t: float) -> None:
        """Seed 001's measurement from this track's own detections, then a filterpy update."""
        self.points = [p, *self.points[:2]]
        self.times = [t, *self.times[:2]]
        var = SIGMA**2
        if len(self.points) < 3:  # a young track measures its position only
            H = np.eye(6)[:2]
            self.kf.update(p, R=np.eye(2) * var, H=H)
            return
        D = difference_operator(self.times[0] - self.times[1], self.times[1] - self.times[2])
        pva = D @ np.array(self.points)                    # (3 derivatives, 2 axes)
        R = np.kron(var * D @ D.T, np.eye(2))              # state order x, y, vx, vy, ax, ay
        self.kf.update(pva.reshape(6), R=R)


def bench_per_track_tracker(pos: np.ndarray) -> float:
    model = ConstantAcceleration(JERK)
    gate = -2.0 * math.log1p(-CFG.gate_probability)
    var = SIGMA**2
    tracks = [_Track(p, 0.0) for p in pos[0]]
    times = []
    for k in range(1, len(pos)):
        dets, t = pos[k], k / FPS
        t0 = time.perf_counter()
        dt = t - tracks[0].times[0]
        F, Q = model.transition(dt), model.Q(dt)
        for trk in tracks:
            trk.kf.predict(F=F, Q=Q)
        pred = np.array([trk.kf.x[:2] for trk in tracks])
        S = np.array([trk.kf.P[:2, :2] for trk in tracks]) + var * np.eye(2)
        Si = np.linalg.inv(S)
        diff = dets[None, :, :] - pred[:, None, :]          # (tracks, detections, 2)
        d2 = np.einsum("tdi,tij,tdj->td", diff, Si, diff)
        cost = np.where(d2 <= gate, d2, 1e9)
        rows, cols = linear_sum_assignment(cost)
        for r, c in zip(rows, cols, strict=True):
            if cost[r, c] <= gate:
                tracks[r].update(dets[c], t)
        times.append(time.perf_counter() - t0)
        assert np.array_equal(cols, np.arange(len(tracks))), "baseline lost a target"
    return _steady(times)


def bench_filters_only(pos: np.ndarray) -> float:
    model = ConstantAcceleration(JERK)
    dt = 1.0 / FPS
    F, Q = model.transition(dt), model.Q(dt)
    # The finite-difference measurements of every frame are formed outside the timed loop,
    # so only filterpy's predict + update are timed (in vtrack's time they are included).
    frames, n = pos.shape[:2]
    t = np.arange(frames) / FPS
    zs, Rs = [], []
    for k in range(1, frames):
        idx = [k, max(k - 1, 0), max(k - 2, 0)]
        z, R, _ = finite_difference_measurement(
            np.swapaxes(pos[idx], 0, 1), np.repeat(t[idx][None] + [0, 0, -1e-3 * (k < 2)], n, 0),
            np.full(n, 3), SIGMA)
        zs.append(z)
        Rs.append(R)
    filters = [_new_filter(p) for p in pos[0]]
    times = []
    for z, R in zip(zs, Rs):
        t0 = time.perf_counter()
        for i, kf in enumerate(filters):
            kf.predict(F=F, Q=Q)
            kf.update(z[i], R=R[i])
        times.append(time.perf_counter() - t0)
    return _steady(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=40)
    args = ap.parse_args()
    print("median ms/frame (ratio = baseline time / vtrack time, same run)")
    print(f"{'targets':>8} {'vtrack':>8} {'per-track tracker':>18} {'ratio':>7}"
          f" {'filters only':>13} {'ratio':>7}")
    for n in (10, 100, 1000):
        pos, w, h = scenario(n, args.frames)
        ours = bench_vtrack(pos, w, h)
        tracker = bench_per_track_tracker(pos)
        filters = bench_filters_only(pos)
        print(f"{n:>8} {ours * 1e3:>8.2f} {tracker * 1e3:>18.2f} {tracker / ours:>6.1f}x"
              f" {filters * 1e3:>13.2f} {filters / ours:>6.1f}x")


if __name__ == "__main__":
    main()
