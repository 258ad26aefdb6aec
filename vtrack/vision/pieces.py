"""Detector stage: blobs read against the tracked vehicles' predicted boxes.

Two rules, each behind its own switch (docs/DETECTOR.md):

- **pieces** (`group_pieces`). A large vehicle of one colour (a white trailer on a pale
  road) comes out of MOG2 with holes, and the cleaning leaves it in pieces, some under the
  noise floor or too ragged for the fill test. Inside the predicted box of a confirmed
  track (grown by `GROW` on each side), the blobs that lie there (`INSIDE` of their box in
  it, their centre in no other predicted box) are one vehicle when none of them would
  pass the blob tests alone: they are joined into one blob (the union of their boxes, the
  sum of their pixels, the hull of their points) before the tests. Pieces that pass alone
  are left to the tracker's fragment stage (tracking/fragments.py): a track may have
  followed two vehicles as one, and joining a passing piece to the small pieces around it
  would hide the second (measured: joining while at most one passes lowers the mast and
  side views' recall). A union
  larger than the grown predicted box is not joined: the expected size of the vehicle at
  that place is the track's predicted box.
- **area cap for new vehicles only** (`area_cap_tracked`). `max_area_fraction` drops a blob
  larger than a share of the frame: no vehicle coming into view is that large, but a truck
  driving up to the camera becomes so. With this switch the cap drops only blobs that no
  predicted box explains, i.e. that match none with IoU >= `MATCH_IOU` (the predicted box
  cut to the image: a vehicle leaving the picture is cut too) and hold fewer than two of
  them (a blob holding several is divided among them by split.py). A blob no tracked
  vehicle makes and no new vehicle could make is rejected.
"""

from __future__ import annotations

import cv2
import numpy as np

from vtrack.boxes import centre, clip, contains, intersection, iou
from vtrack.vision.split import holders

GROW = 0.1        # a predicted box grown by this share of its size on each side
INSIDE = 0.7      # share of a piece's box inside the grown predicted box
MATCH_IOU = 0.5   # a blob this close to a predicted box is that vehicle


def grown(boxes: np.ndarray, share: float) -> np.ndarray:
    """Boxes (K, 4) grown by `share` of their width and height on each side."""
    return boxes + np.column_stack([-share * boxes[:, 2:], 2 * share * boxes[:, 2:]])


def group_pieces(contours: list[np.ndarray], stats: np.ndarray, alone: np.ndarray,
                 priors: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Join the pieces of each predicted box (module docstring). `stats` (N, 5) are the
    blobs' boxes and pixel counts x, y, w, h, n (mask pixels), `alone` (N,) whether each
    passes the blob tests on its own, `priors` (K, 4) the confirmed tracks' predicted boxes
    (mask pixels). Returns the contours and stats with each joined group replaced by one
    blob (its contour the convex hull of the pieces' points)."""
    if len(priors) == 0 or len(stats) < 2:
        return contours, stats
    region = grown(priors, GROW)
    boxes = stats[:, :4]
    within = contains(priors, centre(boxes)).T
    share = intersection(boxes[:, None], region[None]) / np.maximum(
        boxes[:, None, 2] * boxes[:, None, 3], 1e-9)
    member = within & (share >= INSIDE) & (within.sum(axis=1, keepdims=True) == 1)
    used = np.zeros(len(stats), dtype=bool)
    out_c: list[np.ndarray] = []
    out_s: list[np.ndarray] = []
    for k in range(len(priors)):
        idx = np.flatnonzero(member[:, k] & ~used)
        if len(idx) < 2 or alone[idx].any():
            continue
        x0, y0 = boxes[idx, :2].min(axis=0)
        x1, y1 = (boxes[idx, :2] + boxes[idx, 2:]).max(axis=0)
        if x1 - x0 > region[k, 2] or y1 - y0 > region[k, 3]:
            continue
        used[idx] = True
        out_c.append(cv2.convexHull(np.concatenate([contours[i] for i in idx])))
        out_s.append(np.array([x0, y0, x1 - x0, y1 - y0, stats[idx, 4].sum()]))
    if not out_c:
        return contours, stats
    rest = np.flatnonzero(~used)
    return ([contours[i] for i in rest] + out_c,
            np.concatenate([stats[rest], np.array(out_s)]))


def matched(boxes: np.ndarray, priors: np.ndarray, width: float, height: float
            ) -> np.ndarray:
    """(N,) whether each blob box (N, 4) has IoU >= MATCH_IOU with one of the predicted
    boxes (K, 4) cut to the image `width` x `height` (both in the same pixels)."""
    if len(priors) == 0 or len(boxes) == 0:
        return np.zeros(len(boxes), dtype=bool)
    return (iou(boxes, clip(priors, width, height)) >= MATCH_IOU).any(axis=1)


def explained(boxes: np.ndarray, priors: np.ndarray, width: float, height: float
              ) -> np.ndarray:
    """(N,) whether each blob box (N, 4) is explained by the predicted boxes (K, 4), both
    in the same pixels of an image `width` x `height`: `matched` to one of them, or
    holding two or more (split.holders)."""
    several = np.array([len(holders(b, priors)) >= 2 for b in boxes], dtype=bool)
    return matched(boxes, priors, width, height) | several.reshape(-1)
