"""The standing-vehicle hold (vision/hold.py): which predicted boxes stand, MOG2's labels
inside them, and a queued vehicle that stays detected while it stands and leaves no ghost."""

from __future__ import annotations

import numpy as np

from test_motion_detector import Scene
from vtrack.vision.detect import DetectorConfig, MotionDetector
from vtrack.vision.hold import StandingBoxes, held_foreground, hold_mask


def test_a_box_that_stays_put_is_held_between_min_and_max_frames():
    standing = StandingBoxes(speed=0.5, fps=25.0, min_frames=3, max_frames=10)
    still, moving = np.array([50.0, 50, 20, 10]), np.array([100.0, 20, 20, 10])
    held = []
    for n in range(15):
        boxes = np.array([still + [0.05 * (n % 2), 0, 0, 0], moving + [3.0 * n, 0, 0, 0]])
        held.append(standing(boxes))
    counts = [len(h) for h in held]
    assert counts == [0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0], counts
    assert np.allclose(held[5][0, 1:], still[1:])     # the standing one, not the moving one


def test_held_labels_follow_mog2s_tests():
    """Inside the mask: a colour far from the background is foreground (255), a darker copy
    of it is shadow (127), a noisy copy background (0); outside, nothing."""
    bg = np.full((20, 40, 3), 120, np.uint8)
    frame = bg.copy()
    frame[:, :10] = (30, 200, 60)                     # a vehicle
    frame[:, 10:20] = (84, 84, 84)                    # shadow: 0.7 of the road
    frame[:, 20:30] = 123                             # the road, noise of 3 levels
    frame[:, 30:] = (30, 200, 60)                     # a vehicle outside the mask
    held = hold_mask(np.array([[0.0, 0, 30, 20]]), (20, 40))
    labels = held_foreground(frame, bg, held, 16.0, 16.0, 0.5, True)
    assert (labels[:, :10] == 255).all() and (labels[:, 10:20] == 127).all()
    assert (labels[:, 20:] == 0).all()
    assert (held_foreground(frame, bg, held, 16.0, 16.0, 0.5, False)[:, 10:20] == 255).all()


def _queue_scene() -> tuple[Scene, callable]:
    """A car drives in, stands from frame 70 to 260, then drives off."""
    scene = Scene(320, 240, [], seed=11)
    def x_at(n: int) -> float:
        return 10 + 3 * min(n, 70) + 3 * max(n - 260, 0)
    def frame(n: int) -> np.ndarray:
        img = scene.frame(n)
        x = int(x_at(n))
        img[100:124, x:x + 40] = (60, 60, 200)
        return img
    return scene, frame, x_at


def test_a_standing_vehicle_stays_detected_and_leaves_no_ghost():
    """Fed the vehicle's own box as the tracker's prediction: without the hold MOG2 absorbs
    it (and the motion check drops the static blob) within seconds; with it, it is found in
    every frame it stands, and when it drives off nothing is left where it stood."""
    _, frame, x_at = _queue_scene()
    found = {}
    for hold in (False, True):
        det = MotionDetector(DetectorConfig(warmup_frames=10, hold_standing=hold), 320, 240)
        hits = []
        for n in range(300):
            box = np.array([[x_at(n), 100.0, 40, 24]])
            d = det.detect(frame(n), box)
            near = [b for b in d.boxes if abs(b[0] - x_at(n)) < 4 and abs(b[1] - 100) < 4]
            ghost = [b for b in d.boxes if n > 275 and abs(b[0] - x_at(259)) < 8]
            hits.append((len(near) == 1, len(ghost)))
        found[hold] = hits
    standing = range(100, 260)
    assert all(found[True][n][0] for n in standing)
    assert sum(found[False][n][0] for n in standing) < 0.5 * len(standing)
    assert sum(g for _, g in found[True][276:]) == 0
