"""Synthetic traffic: determinism, ground-truth format, physics, pixels and the video file."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vtrack.sim.idm import B_MAX
from vtrack.sim.traffic import (
    KINDS,
    Renderer,
    format_gt,
    ground_truth,
    render_scene,
    simulate_traffic,
)

W, H, FRAMES, FPS = 320, 180, 60, 25.0


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """One small clip rendered once: (folder, SynthResult)."""
    out = tmp_path_factory.mktemp("synth")
    return out, render_scene(out, frames=FRAMES, vehicles=10, width=W, height=H, fps=FPS, seed=5)


@pytest.fixture(scope="module")
def default_traffic():
    """Default-size trajectories for a few seeds (no rendering)."""
    return [simulate_traffic(300, 12, 640, 360, 25.0, seed) for seed in range(4)]


def _gt_text(seed: int) -> str:
    return format_gt(ground_truth(simulate_traffic(FRAMES, 10, W, H, FPS, seed)))


def test_same_seed_same_gt_bytes(rendered, tmp_path):
    folder, _ = rendered
    render_scene(tmp_path, frames=FRAMES, vehicles=10, width=W, height=H, fps=FPS, seed=5)
    assert (tmp_path / "gt.csv").read_bytes() == (folder / "gt.csv").read_bytes()
    assert _gt_text(5) == (folder / "gt.csv").read_text()
    assert _gt_text(6) != _gt_text(5)


def test_gt_rows_are_sorted_clipped_and_valid(rendered):
    folder, res = rendered
    rows = np.loadtxt(folder / "gt.csv", delimiter=",", ndmin=2)
    assert rows.shape == (res.gt_rows, 11)
    assert np.array_equal(np.lexsort((rows[:, 1], rows[:, 0])), np.arange(len(rows)))
    assert rows[:, 0].min() >= 1 and rows[:, 0].max() <= FRAMES
    left, top, w, h = rows[:, 2:6].T
    assert np.all((left >= 0) & (top >= 0) & (w > 0) & (h > 0))
    assert np.all((left + w <= W) & (top + h <= H))
    assert np.all(rows[:, 6] == 1) and np.all(rows[:, 7:10] == -1)
    assert np.all((rows[:, 10] >= 0) & (rows[:, 10] <= 1))


def test_occluder_hides_vehicles_and_both_directions_drive(default_traffic):
    for traj in default_traffic:
        rows = ground_truth(traj)
        inside = (rows[:, 2] > 0) & (rows[:, 2] + rows[:, 4] < 640)   # not cut by the border
        assert np.any(inside & (rows[:, 10] < 1)), "the occluders hide vehicles"
        assert np.any(inside & (rows[:, 10] < 0.3)), "some vehicle is almost hidden"
        directions = set()
        for vid in np.unique(rows[:, 1]):
            centre = rows[rows[:, 1] == vid, 2] + rows[rows[:, 1] == vid, 4] / 2
            directions.add(np.sign(centre[-1] - centre[0]))
        assert {-1.0, 1.0} <= directions


def test_motion_is_smooth_and_lanes_never_overlap(default_traffic):
    for traj in default_traffic:
        ppm, dt = traj.layout.px_per_m, 1 / traj.fps
        a_top = max(kind[4] for kind in KINDS.values())
        assert np.nanmin(traj.a) >= -B_MAX * ppm - 1e-9
        assert np.nanmax(traj.a) <= a_top * ppm + 1e-9
        assert np.nanmin(traj.v) >= 0
        ds = np.diff(traj.s, axis=1)
        v_mid = 0.5 * (traj.v[:, 1:] + traj.v[:, :-1])
        assert np.nanmax(np.abs(ds - v_mid * dt)) < 1e-3 * ppm, "s' = v (to a millimetre)"
        assert np.nanmax(np.abs(np.diff(traj.a, axis=1))) < 0.5 * ppm, "acceleration is smooth"
        assert np.nanmin(traj.a) < -0.5 * ppm and np.nanmax(traj.a) > 0.5 * ppm
        _assert_no_overlap(traj)


def _assert_no_overlap(traj) -> None:
    lefts = traj.lefts()
    for n in range(traj.frames):
        for lane in range(len(traj.layout.lanes)):
            ks = [k for k, veh in enumerate(traj.vehicles)
                  if veh.lane == lane and not np.isnan(traj.s[k, n])]
            spans = sorted((lefts[k, n], lefts[k, n] + traj.vehicles[k].length) for k in ks)
            assert all(a[1] <= b[0] for a, b in zip(spans, spans[1:])), f"frame {n + 1}"


def test_rendered_vehicles_are_exactly_where_gt_says():
    traj = simulate_traffic(80, 10, W, H, FPS, 3)
    rows = ground_truth(traj)
    renderer = Renderer(traj, 3)
    empty = renderer.empty()
    for n in range(0, 80, 9):
        changed = np.any(renderer.clean(n) != empty, axis=2)
        boxes = np.zeros_like(changed)
        for row in rows[rows[:, 0] == n + 1]:
            left, top, w, h = row[2:6].astype(int)
            boxes[top:top + h, left:left + w] = True
            if row[10] == 1:   # fully visible: the painted pixels span the whole box
                ys, xs = np.nonzero(changed[top:top + h, left:left + w])
                assert (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1) == (0, 0, w, h)
        assert not np.any(changed & ~boxes), f"paint outside the gt boxes in frame {n + 1}"


def test_video_decodes_with_vehicles_in_the_gt_boxes(rendered):
    folder, res = rendered
    cap = cv2.VideoCapture(str(folder / "video.avi"))
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    cap.release()
    assert res.video == folder / "video.avi" and len(frames) == FRAMES
    assert frames[0].shape == (H, W, 3)
    traj = simulate_traffic(FRAMES, 10, W, H, FPS, 5)
    empty = Renderer(traj, 5).empty().astype(float)
    rows = ground_truth(traj)
    for row in rows[(rows[:, 10] == 1) & (rows[:, 0] % 10 == 0)]:
        left, top, w, h = row[2:6].astype(int)
        diff = np.abs(frames[int(row[0]) - 1].astype(float) - empty).mean(axis=2)
        box = diff[top:top + h, left:left + w].mean()
        outside = diff.copy()
        outside[max(top - 3, 0):top + h + 3, max(left - 3, 0):left + w + 3] = np.nan
        assert box > 3 * np.nanmedian(outside), f"vehicle {int(row[1])} frame {int(row[0])}"
