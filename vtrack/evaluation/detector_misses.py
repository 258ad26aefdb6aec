"""Why the detector misses ground truth: each visible ground-truth box of a frame that no
detection matches one to one at IoU >= 0.5 (the match of `detection_scores`, the tracker's
ceiling) is put in one class by the detection that covers most of it:

- ``none``: detections cover less than 30 % of it (MOG2 saw too little, or the blob was
  dropped by the noise floor, the fill or the motion test);
- ``merged``: one detection covers >= 60 % of it and is more than 1.6x its area (one blob
  holds it and something else: a neighbour, a shadow, a ghost);
- ``fragment``: the best detection is less than 0.6x its area (part of it);
- ``offset``: the rest (about the right size, misplaced).

The misses of class ``none`` are then counted by the box's side sqrt(w h) and its speed in
pixels per frame (the centre's displacement over +-2 frames, which averages out a camera's
sway), the two things that decide whether background subtraction sees a vehicle: a small
far vehicle falls under the noise floor, a slow or standing one melts into the background
(or was in the frames the background was estimated from).
"""

from __future__ import annotations

import numpy as np

from vtrack.boxes import intersection
from vtrack.evaluation.mot import ignore_mask, match_boxes

CLASSES = ("matched", "none", "merged", "fragment", "offset")
SIDE_EDGES = (0.0, 15.0, 30.0, np.inf)     # px: far, middle, near vehicles
SPEED_EDGES = (0.0, 0.5, 2.0, np.inf)      # px/frame: standing, slow, moving
SPEED_SPAN = 2                             # frames either side for the speed


def gt_speed(gt: np.ndarray) -> np.ndarray:
    """(N,) speed of each ground-truth row (MOT columns), px/frame: the centre's displacement
    between SPEED_SPAN frames before and after it (fewer at the ends of a track), divided by
    the frames between them; 0 for a track seen in one frame."""
    speed = np.zeros(len(gt))
    centre = gt[:, 2:4] + gt[:, 4:6] / 2
    for ident in np.unique(gt[:, 1]):
        rows = np.flatnonzero(gt[:, 1] == ident)
        rows = rows[np.argsort(gt[rows, 0])]
        if len(rows) < 2:
            continue
        k = np.arange(len(rows))
        lo, hi = np.maximum(k - SPEED_SPAN, 0), np.minimum(k + SPEED_SPAN, len(rows) - 1)
        frames = gt[rows[hi], 0] - gt[rows[lo], 0]
        step = np.linalg.norm(centre[rows[hi]] - centre[rows[lo]], axis=1)
        speed[rows] = step / np.maximum(frames, 1)
    return speed


def classify_misses(gt: np.ndarray, detections: np.ndarray) -> np.ndarray:
    """(N,) class index into CLASSES of each visible ground-truth row (rows of MOT columns,
    the 11th the visible fraction; ignore rows (mot.ignore_mask) get -1) against per-frame
    detections (MOT columns, ids ignored)."""
    out = np.full(len(gt), -1)
    visible = ~ignore_mask(gt)
    for frame in np.unique(gt[visible, 0]):
        gi = np.flatnonzero(visible & (gt[:, 0] == frame))
        g = gt[gi, 2:6]
        d = detections[detections[:, 0] == frame, 2:6]
        if len(d) == 0:
            out[gi] = CLASSES.index("none")
            continue
        cls = np.full(len(gi), -1)
        cls[match_boxes(g, d)[0]] = CLASSES.index("matched")
        covered = intersection(g[:, None], d[None]) / np.maximum(g[:, 2:3] * g[:, 3:4], 1e-9)
        best = covered.argmax(axis=1)
        share = covered[np.arange(len(gi)), best]
        ratio = d[best, 2] * d[best, 3] / np.maximum(g[:, 2] * g[:, 3], 1e-9)
        why = np.select([share < 0.3, (share >= 0.6) & (ratio > 1.6), ratio < 0.6],
                        [CLASSES.index("none"), CLASSES.index("merged"),
                         CLASSES.index("fragment")], CLASSES.index("offset"))
        out[gi] = np.where(cls < 0, why, cls)
    return out


def miss_table(gt: np.ndarray, detections: np.ndarray) -> dict[str, object]:
    """Shares of the visible ground truth per class (`shares`), the number of visible rows
    (`rows`) and, per side band x speed band, the rows and the share of them in class
    ``none`` (`none_by_side_speed`: {"side lo-hi": {"speed lo-hi": [rows, share]}})."""
    cls = classify_misses(gt, detections)
    keep = cls >= 0
    cls, rows = cls[keep], gt[keep]
    side = np.sqrt(rows[:, 4] * rows[:, 5])
    speed = gt_speed(gt)[keep]
    n = max(len(cls), 1)
    table: dict[str, dict[str, list[float]]] = {}
    for s0, s1 in zip(SIDE_EDGES[:-1], SIDE_EDGES[1:]):
        band = {}
        for v0, v1 in zip(SPEED_EDGES[:-1], SPEED_EDGES[1:]):
            m = (side >= s0) & (side < s1) & (speed >= v0) & (speed < v1)
            none = float(np.mean(cls[m] == CLASSES.index("none"))) if m.any() else 0.0
            band[f"{v0:g}-{v1:g}"] = [int(m.sum()), none]
        table[f"{s0:g}-{s1:g}"] = band
    return {"rows": int(len(cls)),
            "shares": {c: float(np.sum(cls == i) / n) for i, c in enumerate(CLASSES)},
            "none_by_side_speed": table}
