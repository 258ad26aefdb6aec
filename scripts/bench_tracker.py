"""Per-frame tracker time at 10, 100 and 1000 simultaneous targets: vtrack's batched tracker
(prediction, k-d-tree gating, per-group assignment, batched Joseph update, lifecycle) next to
a plain per-track filterpy loop (predict + update of one KalmanFilter object per target, with
the association given for free) on the same detections, measured in one run.

    .venv/bin/python scripts/bench_tracker.py [--frames 60]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from vtrack.estimation.models import ConstantAcceleration
from vtrack.tracking.measurements import finite_difference_measurement
from vtrack.tracking.tracker import Tracker, TrackerConfig

FPS = 25.0


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
    boxes[:, 2:] = 30.0
    times = []
    for k, p in enumerate(pos):
        boxes[:, :2] = p - 15.0
        t0 = time.perf_counter()
        tr.step(k + 1, k / FPS, p, boxes)
        times.append(time.perf_counter() - t0)
    assert len(tr) == pos.shape[1], "every target should still be tracked"
    return float(np.median(times[5:]))


def bench_filterpy(pos: np.ndarray) -> float:
    from filterpy.kalman import KalmanFilter

    model = ConstantAcceleration(TrackerConfig().jerk_psd)
    dt = 1.0 / FPS
    F, Q = model.transition(dt), model.Q(dt)
    sigma = TrackerConfig().detection_sigma
    # The finite-difference measurements of every frame are formed outside the timed loop,
    # so only filterpy's predict + update are timed (in vtrack's time they are included).
    frames, n = pos.shape[:2]
    t = np.arange(frames) / FPS
    zs, Rs = [], []
    for k in range(1, frames):
        idx = [k, max(k - 1, 0), max(k - 2, 0)]
        z, R, _ = finite_difference_measurement(
            np.swapaxes(pos[idx], 0, 1), np.repeat(t[idx][None] + [0, 0, -1e-3 * (k < 2)], n, 0),
            np.full(n, 3), sigma)
        zs.append(z)
        Rs.append(R)
    filters = []
    for p in pos[0]:
        kf = KalmanFilter(dim_x=6, dim_z=6)
        kf.F, kf.Q, kf.H = F, Q, np.eye(6)
        kf.x = np.array([p[0], p[1], 0, 0, 0, 0.0])
        kf.P = np.diag([sigma**2] * 2 + [150.0**2] * 2 + [100.0**2] * 2)
        filters.append(kf)
    times = []
    for z, R in zip(zs, Rs):
        t0 = time.perf_counter()
        for i, kf in enumerate(filters):
            kf.predict()
            kf.update(z[i], R=R[i])
        times.append(time.perf_counter() - t0)
    return float(np.median(times[5:]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=40)
    args = ap.parse_args()
    print(f"{'targets':>8} {'vtrack ms/frame':>16} {'filterpy loop ms/frame':>23} {'ratio':>7}")
    for n in (10, 100, 1000):
        pos, w, h = scenario(n, args.frames)
        ours = bench_vtrack(pos, w, h)
        ref = bench_filterpy(pos)
        print(f"{n:>8} {ours * 1e3:>16.2f} {ref * 1e3:>23.2f} {ref / ours:>6.1f}x")


if __name__ == "__main__":
    main()
