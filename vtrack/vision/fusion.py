"""Fusion of one frame's motion blobs (MOG2) and appearance boxes (YOLOX) into one set of
detections, each with its provenance (MOTION, APPEARANCE or BOTH), a score and a class.

A blob and an appearance box are linked when their intersection covers at least
`LINK_SHARE` of the smaller of the two (one holds the other: a vehicle in a merged blob, a
piece of a vehicle inside its box). Then, per blob:
- two or more linked appearance boxes split it: the blob is replaced by them (BOTH): two
  cars merged along the line of sight, a car and a motorcycle, a row of riders;
- one linked appearance box that covers at least `COVER_SHARE` of its box explains it: the
  blob is replaced by it (BOTH): the vehicle without the blob's shadow, a truck broken into
  pieces made whole;
- otherwise the blob stays a detection (MOTION): the model sees its vehicle only partly,
  or not at all (seen from straight above, a type it was not trained on), and appearance
  adds evidence where it has some; it never vetoes a moving blob.
Appearance boxes linked to no blob (standing, queued, far vehicles) are detections of
their own (APPEARANCE); those linked only to blobs they do not explain are dropped (the
blob measures that vehicle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtrack.boxes import intersection
from vtrack.vision.appearance import AppearanceBoxes

MOTION, APPEARANCE, BOTH = 0, 1, 2
PROVENANCE = ("motion", "appearance", "both")
LINK_SHARE = 0.5
COVER_SHARE = 0.5


@dataclass
class Fused:
    """One frame's fused detections: boxes (K, 4), foreground areas (K,) (a box's area
    where no blob measured it), provenance (K,), scores (K,) (1 for motion-only blobs) and
    classes (K,) (index into appearance.VEHICLE_CLASSES, -1 unknown)."""

    boxes: np.ndarray
    areas: np.ndarray
    source: np.ndarray
    score: np.ndarray
    cls: np.ndarray


def links(blobs: np.ndarray, app: np.ndarray) -> np.ndarray:
    """(B, A) whether blob b and appearance box a hold one another (LINK_SHARE)."""
    if not len(blobs) or not len(app):
        return np.zeros((len(blobs), len(app)), dtype=bool)
    inter = intersection(blobs[:, None], app[None])
    smaller = np.minimum(np.prod(blobs[:, 2:], axis=1)[:, None],
                         np.prod(app[:, 2:], axis=1)[None])
    return inter >= LINK_SHARE * np.maximum(smaller, 1e-9)


def coverage(blob: np.ndarray, boxes: np.ndarray) -> float:
    """The share of `blob`'s box (4,) covered by the union of `boxes` (n, 4), on a grid of
    the blob's box (16 x 16 cells)."""
    if not len(boxes) or blob[2] <= 0 or blob[3] <= 0:
        return 0.0
    u = blob[0] + (np.arange(16) + 0.5) * blob[2] / 16
    v = blob[1] + (np.arange(16) + 0.5) * blob[3] / 16
    inside_u = (u[None] >= boxes[:, :1]) & (u[None] < boxes[:, :1] + boxes[:, 2:3])
    inside_v = (v[None] >= boxes[:, 1:2]) & (v[None] < boxes[:, 1:2] + boxes[:, 3:4])
    covered = (inside_v[:, :, None] & inside_u[:, None, :]).any(axis=0)
    return float(covered.mean())


def fuse(blobs: np.ndarray, areas: np.ndarray, app: AppearanceBoxes) -> Fused:
    """The fused detections of motion blobs (B, 4) with foreground areas (B,) and the
    appearance boxes `app` of the same frame and pixels (see the module's rules). Motion
    rows come first in blob order, then appearance rows in `app`'s order."""
    link = links(blobs, app.boxes)
    explained = np.array([link[b].sum() >= 2
                          or coverage(blobs[b], app.boxes[link[b]]) >= COVER_SHARE
                          for b in range(len(blobs))], dtype=bool)
    motion = ~explained
    # an appearance box is kept if it explains a blob or is linked to none
    keep_app = link[explained].any(axis=0) | ~link.any(axis=0)
    both = link[explained].any(axis=0)
    a = np.flatnonzero(keep_app)
    app_boxes = app.boxes[a]
    return Fused(
        boxes=np.concatenate([blobs[motion], app_boxes]).reshape(-1, 4),
        areas=np.concatenate([areas[motion], np.prod(app_boxes[:, 2:], axis=1)]),
        source=np.concatenate([np.full(int(motion.sum()), MOTION),
                               np.where(both[a], BOTH, APPEARANCE)]).astype(int),
        score=np.concatenate([np.ones(int(motion.sum())), app.scores[a]]),
        cls=np.concatenate([np.full(int(motion.sum()), -1), app.classes[a]]).astype(int))
