"""A coasting track whose prediction has driven out of the picture has left it
(lifecycle.Deleter._leaving): a vehicle entering where it left gets a new id."""

from __future__ import annotations

import numpy as np

from vtrack.app.config import AppConfig
from vtrack.boxes import centre, clip
from vtrack.tracking.tracker import Tracker

W, H, FPS = 640, 360, 25.0


def test_a_vehicle_entering_where_one_left_is_a_new_one() -> None:
    tracker = Tracker(AppConfig().tracker, W, H, FPS)
    ids: dict[str, set[int]] = {"leaving": set(), "entering": set()}
    for n in range(80):
        t = n / FPS
        leaving = clip(np.array([[400.0 - 12 * n, 150.0, 160.0, 80.0]]), W, H)
        entering = clip(np.array([[-160.0 + 12 * (n - 41), 160.0, 160.0, 80.0]]), W, H)
        # each is detected while at least 30 % of it is in view
        boxes = [b for b, k in ((leaving, "leaving"), (entering, "entering"))
                 if b[0, 2] >= 0.3 * 160.0]
        boxes = np.vstack(boxes) if boxes else np.zeros((0, 4))
        out = tracker.step(n + 1, t, centre(boxes), boxes)
        for k, box in (("leaving", leaving), ("entering", entering)):
            if box[0, 2] >= 0.3 * 160.0:
                hit = np.flatnonzero(np.all(np.abs(out.boxes - box) < 8.0, axis=1))
                ids[k].update(int(i) for i in out.ids[hit])
    assert ids["leaving"] and ids["entering"]
    assert not ids["leaving"] & ids["entering"]
