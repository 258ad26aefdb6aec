"""Fusion of one frame's motion blobs (MOG2) and appearance boxes (YOLOX) into one set of
detections, each with its provenance (MOTION, APPEARANCE or BOTH), a score and a class.

A blob and an appearance box are linked when their intersection covers at least
`LINK_SHARE` of the smaller of the two (one holds the other: a vehicle in a merged blob, a
piece of a vehicle inside its box). Then, per blob:
- two or more linked appearance boxes split it: the blob is replaced by them (BOTH): two
  cars merged along the line of sight, a car and a motorcycle, a row of riders;
- one linked appearance box that covers at least `COVER_SHARE` of its box explains it: the
  blob is replaced by it (BOTH): the vehicle without the blob's shadow, a truck broken into
  pieces made whole; but where the box is small in the model's own pixels (under
  `SMALL_MODEL_PX` on a side: a far vehicle, whose box the model places to a few pixels)
  the blob keeps its geometry and takes the box's class and score (BOTH);
- otherwise the blob stays a detection (MOTION): the model sees its vehicle only partly,
  or not at all (seen from straight above, a type it was not trained on), and appearance
  adds evidence where it has some; it never vetoes a moving blob.
Appearance boxes linked to no blob (standing, queued, far vehicles) are detections of
their own (APPEARANCE) when their score reaches `alone_score`, higher than the model's own
floor (one source of evidence, not two: a low score on a shadow or a patch of road starts a
track that nothing moves); those linked only to blobs they do not explain are dropped (the
blob measures that vehicle).

Between two appearance passes (`follow`) each appearance box rides on the blobs it
explained (its carrier: their union): on the next frame the blobs linked to the carrier are
its new carrier, and the box keeps its place and size relative to it (the box in the
carrier's own coordinates, `relative` / `placed`). So the tracker is measured with the same
whole boxes on every frame, not whole boxes on pass frames and blobs with their shadows,
merges and pieces on the frames between. A carrier whose size has changed by more than
`CARRIER_CHANGE` since the pass (another vehicle merged into the blob, the vehicle left it)
drops its riders and the blobs are motion detections again until the next pass. A box with
no carrier (a standing vehicle) is held while no blob links to it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtrack.boxes import enclosing, intersection
from vtrack.vision.appearance import AppearanceBoxes

MOTION, APPEARANCE, BOTH = 0, 1, 2
PROVENANCE = ("motion", "appearance", "both")
LINK_SHARE = 0.5
COVER_SHARE = 0.5
SMALL_MODEL_PX = 24.0  # a box smaller than this on a side, in model pixels, is placed loosely
CARRIER_CHANGE = 1.25  # largest ratio of a carrier's width or height to those at the pass


@dataclass
class Fused:
    """One frame's fused detections: boxes (K, 4), foreground areas (K,) (a box's area
    where no blob measured it), provenance (K,), scores (K,) (1 for motion-only blobs) and
    classes (K,) (index into appearance.VEHICLE_CLASSES, -1 unknown); for each row of an
    appearance box, the union of the blobs it explained (its carrier; NaN: none) (K, 4),
    and that carrier as it was at the appearance pass (`first`, K, 4)."""

    boxes: np.ndarray
    areas: np.ndarray
    source: np.ndarray
    score: np.ndarray
    cls: np.ndarray
    carrier: np.ndarray
    first: np.ndarray

    def riders(self) -> Fused:
        """The appearance rows (those that ride on to the next frame, `follow`)."""
        keep = self.source != MOTION
        return Fused(self.boxes[keep], self.areas[keep], self.source[keep], self.score[keep],
                     self.cls[keep], self.carrier[keep], self.first[keep])

    @staticmethod
    def empty() -> Fused:
        return Fused(np.zeros((0, 4)), np.zeros(0), np.zeros(0, int), np.zeros(0),
                     np.zeros(0, int), np.zeros((0, 4)), np.zeros((0, 4)))


def relative(boxes: np.ndarray, carriers: np.ndarray) -> np.ndarray:
    """Boxes (n, 4) in their carriers' (n, 4) coordinates: the carrier is (0, 0, 1, 1)."""
    size = np.maximum(carriers[:, 2:], 1e-9)
    return np.concatenate([(boxes[:, :2] - carriers[:, :2]) / size, boxes[:, 2:] / size],
                          axis=1)


def placed(rel: np.ndarray, carriers: np.ndarray) -> np.ndarray:
    """Boxes (n, 4) given in carrier coordinates `rel` placed on `carriers` (n, 4)."""
    return np.concatenate([carriers[:, :2] + rel[:, :2] * carriers[:, 2:],
                           rel[:, 2:] * carriers[:, 2:]], axis=1)


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


def fuse(blobs: np.ndarray, areas: np.ndarray, app: AppearanceBoxes, alone_score: float = 0.0
         ) -> Fused:
    """The fused detections of motion blobs (B, 4) with foreground areas (B,) and the
    appearance boxes `app` of the same frame and pixels (see the module's rules; boxes on no
    blob need `alone_score`). Motion rows come first in blob order, then appearance rows in
    `app`'s order."""
    link = links(blobs, app.boxes)
    explained = np.array([link[b].sum() >= 2
                          or coverage(blobs[b], app.boxes[link[b]]) >= COVER_SHARE
                          for b in range(len(blobs))], dtype=bool)
    motion = ~explained
    # an appearance box is kept if it explains a blob or is linked to none
    keep_app = link[explained].any(axis=0) | (~link.any(axis=0) & (app.scores >= alone_score))
    both = link[explained].any(axis=0)
    a = np.flatnonzero(keep_app)
    boxes, box_areas = app.boxes[a].copy(), np.prod(app.boxes[a, 2:], axis=1)
    small = app.boxes[a, 2:].min(axis=1) * app.scale < SMALL_MODEL_PX
    carriers = np.full((len(a), 4), np.nan)
    for row, k in enumerate(a):
        held = np.flatnonzero(link[:, k] & explained)
        if not len(held):
            continue
        carriers[row] = enclosing(blobs[held])
        if small[row] and len(held) == 1 and link[held[0]].sum() == 1:
            boxes[row], box_areas[row] = blobs[held[0]], areas[held[0]]
    return _joined(blobs[motion], areas[motion], Fused(
        boxes, box_areas, np.where(both[a], BOTH, APPEARANCE).astype(int), app.scores[a],
        app.classes[a].astype(int), carriers, carriers.copy()))


def _joined(blobs: np.ndarray, areas: np.ndarray, app: Fused) -> Fused:
    """Motion rows (the blobs) followed by the appearance rows `app`."""
    n = len(blobs)
    return Fused(np.concatenate([blobs.reshape(-1, 4), app.boxes]).reshape(-1, 4),
                 np.concatenate([areas, app.areas]),
                 np.concatenate([np.full(n, MOTION), app.source]).astype(int),
                 np.concatenate([np.ones(n), app.score]),
                 np.concatenate([np.full(n, -1), app.cls]).astype(int),
                 np.concatenate([np.full((n, 4), np.nan), app.carrier]),
                 np.concatenate([np.full((n, 4), np.nan), app.first]))


def follow(riders: Fused, blobs: np.ndarray, areas: np.ndarray) -> Fused:
    """This frame's detections between two appearance passes: the appearance boxes of the
    last frame (`riders`, Fused.riders) carried on by this frame's blobs (B, 4) or held
    where they stand, and the blobs no rider takes as motion detections (the module's
    rules)."""
    carried = ~np.isnan(riders.carrier[:, 0])
    taken = np.zeros(len(blobs), dtype=bool)
    keep = np.zeros(len(riders.boxes), dtype=bool)
    boxes, carriers = riders.boxes.copy(), riders.carrier.copy()
    link = links(riders.carrier[carried], blobs) if carried.any() else None
    for i, r in enumerate(np.flatnonzero(carried)):
        held = link[i]
        if not held.any():
            continue
        new = enclosing(blobs[held])
        change = new[2:] / np.maximum(riders.first[r, 2:], 1e-9)
        if np.any((change > CARRIER_CHANGE) | (change < 1 / CARRIER_CHANGE)):
            continue
        rel = relative(riders.boxes[r][None], riders.carrier[r][None])
        boxes[r], carriers[r] = placed(rel, new[None])[0], new
        taken |= held
        keep[r] = True
    standing = np.flatnonzero(~carried)
    if len(standing):
        keep[standing] = ~links(blobs, riders.boxes[standing]).any(axis=0)
    k = np.flatnonzero(keep)
    return _joined(blobs[~taken], areas[~taken], Fused(
        boxes[k], np.prod(boxes[k, 2:], axis=1), riders.source[k], riders.score[k],
        riders.cls[k], carriers[k], riders.first[k]))
