"""The ground truth as detections: a tracker's own ceiling, with the detector taken out.

`oracle_detections` turns ground-truth rows (MOTChallenge, an 11th column of visibility)
into per-frame detections. It keeps the boxes the scoring counts, optionally with a
controlled amount of edge noise and random drops. A tracker fed with them loses only what
is its own.

`tracked_rows` runs a tracker with vtrack's `step` interface on them and returns its rows
(`mot_array`: MOTChallenge rows, as read_mot gives them).

`unmoved_ignored` marks as ignore regions the rows of a vehicle before it first moves;
`moved_share` is the share of the scored rows it leaves, the ceiling of a motion
detector's MOTA on the full ground truth.
Background subtraction cannot see a vehicle that stands from the first frame, and a
motion tracker does not confirm one (a static blob is noise or a ghost to it). With this
marking such vehicles cost it nothing. A tracker that does follow them gains nothing
either: its rows matched to ignore regions are dropped (mot.drop_ignored).

`hidden_crossings` is the counting lines' ceiling: the true crossings of vehicles out of the
camera's sight on one side of the line, which a counter on the video can only guess.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtrack.analytics.lines import LineCounter
from vtrack.evaluation.mot import MIN_VISIBILITY, ignore_mask


def oracle_detections(gt: np.ndarray, noise: float = 0.0, drop: float = 0.0,
                      rng: np.random.Generator | None = None) -> np.ndarray:
    """Detections (D, 5): frame, x, y, w, h, from ground-truth rows (N, >= 7).

    Keeps the rows the scoring counts (conf != 0, visibility >= MIN_VISIBILITY when
    given). Each box edge moves by N(0, (noise * sqrt(w h))^2), the sides are kept at
    1 px or more, then each box is dropped with probability `drop`."""
    if not (noise >= 0 and 0 <= drop <= 1):
        raise ValueError("noise must be >= 0 and drop in [0, 1]")
    rng = rng if rng is not None else np.random.default_rng(0)
    keep = gt[:, 6] != 0
    if gt.shape[1] >= 11:
        keep &= gt[:, 10] >= MIN_VISIBILITY
    rows = gt[keep]
    x0, y0 = rows[:, 2], rows[:, 3]
    x1, y1 = x0 + rows[:, 4], y0 + rows[:, 5]
    if noise > 0:
        sd = noise * np.sqrt(rows[:, 4] * rows[:, 5])
        x0, y0, x1, y1 = (v + rng.standard_normal(len(rows)) * sd for v in (x0, y0, x1, y1))
    boxes = np.column_stack([rows[:, 0], x0, y0, np.maximum(x1 - x0, 1.0),
                             np.maximum(y1 - y0, 1.0)])
    if drop > 0:
        boxes = boxes[rng.random(len(boxes)) >= drop]
    return boxes


def unmoved_ignored(gt: np.ndarray, motion: float = 0.5) -> np.ndarray:
    """A copy of ground-truth rows with conf 0 (an ignore region) on each vehicle's rows
    before its box centre first lies `motion` box scales sqrt(w h) from where it was in
    its first row."""
    out = gt.copy()
    for vid in np.unique(gt[:, 1]):
        idx = np.flatnonzero(gt[:, 1] == vid)
        idx = idx[np.argsort(gt[idx, 0])]
        rows = gt[idx]
        centre = rows[:, 2:4] + rows[:, 4:6] / 2
        away = np.hypot(*(centre - centre[0]).T) >= motion * np.sqrt(rows[:, 4] * rows[:, 5])
        first = int(np.argmax(away)) if away.any() else len(rows)
        out[idx[:first], 6] = 0
    return out


def moved_visible(gt: np.ndarray, min_visible: float = 0.7) -> np.ndarray:
    """`unmoved_ignored(gt)` with the rows under `min_visible` visible (the 11th column)
    also ignore regions: the boxes a motion detector's blob can match one to one (a whole-
    vehicle box mostly hidden behind another cannot match the blob of its visible part)."""
    out = unmoved_ignored(gt)
    if gt.shape[1] >= 11:
        out[gt[:, 10] < min_visible, 6] = 0
    return out


def moved_share(gt: np.ndarray, marked: np.ndarray) -> float:
    """The share of the scored ground-truth rows (mot.ignore_mask) that `marked`, the same
    rows marked by `unmoved_ignored`, still scores: those whose vehicle has moved. The
    others stand where the background estimated from the video holds them, so a tracker on
    background subtraction matches none of them, and its MOTA on the full ground truth is
    at most this (nan without scored rows)."""
    scored = ~ignore_mask(gt)
    if not scored.any():
        return float("nan")
    return float(np.mean(~ignore_mask(marked)[scored]))


def hidden_crossings(gt: np.ndarray, lines: Sequence[Sequence[float]]) -> list[list[int]]:
    """[forward, backward] per line of the ground truth's crossings (counted by the rule of
    `vtrack track`, analytics/lines.py) made out of the camera's sight: the vehicle is
    under MIN_VISIBILITY visible (the 11th column) in the frames either side of the
    crossing, and it is not seen (at least MIN_VISIBILITY visible) both before and after
    them, so no tracker follows it across; one that coasts on its prediction can only
    guess the crossing. A vehicle that crosses behind a bus and is seen on both sides is
    not hidden. Without a visibility column nothing is hidden."""
    out = [[0, 0] for _ in lines]
    if gt.shape[1] < 11 or not len(gt):
        return out
    counter = LineCounter(lines)
    rows = gt[np.lexsort((gt[:, 0], gt[:, 1]))]
    starts = np.flatnonzero(np.r_[True, rows[1:, 1] != rows[:-1, 1]])
    for a, b in zip(starts, np.r_[starts[1:], len(rows)], strict=True):
        seen = rows[a:b, 10] >= MIN_VISIBILITY
        for k in range(a, b):
            for c in counter.add(int(rows[k, 1]), int(rows[k, 0]), 0.0,
                                 rows[k, 2:4] + rows[k, 4:6] / 2):
                i = k - a                              # the row that completes the crossing
                if seen[i] or (i > 0 and seen[i - 1]):
                    continue
                if not (seen[:i].any() and seen[i:].any()):
                    out[c.line][0 if c.direction == "forward" else 1] += 1
        counter.forget(int(rows[a, 1]))
    return out


def tracked_rows(tracker: Any, dets: np.ndarray, frames: int, fps: float,
                 whole: bool = False, video: str | Path | None = None) -> np.ndarray:
    """MOT rows (R, 10), sorted by frame then id, of `tracker` (vtrack's Tracker, or any
    object whose step(frame, t, centres, boxes) returns FrameTracks) run on detections
    (frame, x, y, w, h) over frames 1..frames at `fps`. `whole`: the detections are given
    as boxes the appearance model drew (`seen`, tracking/provenance.py), else as motion
    blobs. `video`: the clip, whose frames give the boxes their colour signatures
    (vision/colour.py; vtrack's re-identification reads them). A row emitted again for the
    same (frame, id) replaces the earlier one."""
    rows: dict[tuple[int, int], np.ndarray] = {}
    reader = None
    if video is not None:
        import cv2

        from vtrack.vision.colour import signatures

        reader = cv2.VideoCapture(str(video))
    try:
        for n in range(1, frames + 1):
            d = dets[dets[:, 0] == n, 1:5]
            extra: dict[str, Any] = {"seen": np.ones(len(d), dtype=bool)} if whole else {}
            if reader is not None:
                ok, image = reader.read()
                if ok:
                    extra["colours"] = signatures(image, d)
            for r in tracker.step(n, (n - 1) / fps, d[:, :2] + d[:, 2:] / 2, d, **extra).rows:
                rows[int(r[0]), int(r[1])] = r[:6]
    finally:
        if reader is not None:
            reader.release()
    return mot_array(np.array([rows[k] for k in sorted(rows)]).reshape(-1, 6))


def mot_array(rows: np.ndarray) -> np.ndarray:
    """Rows (R, 6) of frame, id, x, y, w, h as MOTChallenge rows (R, 10): conf 1, the
    world coordinates -1."""
    return np.hstack([rows, np.tile([1.0, -1.0, -1.0, -1.0], (len(rows), 1))])
