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

Passes look at the whole frame or at one tile of it (`renew`). The whole frame is in
charge of the vehicles it sees well enough (SMALL_MODEL_PX), a tile of the far ones the
whole frame shows too small: a tile's pass gives only such boxes and renews only such
riders inside it, and a whole-frame pass keeps the riders a finer pass found that it shows
too small and has no box of (their vehicles ride on until their tile's next pass).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtrack.boxes import enclosing, enclosing_each, intersection
from vtrack.vision.appearance import AppearanceBoxes

MOTION, APPEARANCE, BOTH = 0, 1, 2
PROVENANCE = ("motion", "appearance", "both")
LINK_SHARE = 0.5
COVER_SHARE = 0.5
SMALL_MODEL_PX = 24.0  # a box smaller than this on a side, in model pixels, is placed loosely
CARRIER_CHANGE = 1.25  # largest ratio of a carrier's width or height to those at the pass
FINER = 1.2  # a whole-frame pass within this factor of a rider's pass's scale looks as finely


@dataclass
class Fused:
    """One frame's fused detections: boxes (K, 4), foreground areas (K,) (a box's area
    where no blob measured it), provenance (K,), scores (K,) (1 for motion-only blobs) and
    classes (K,) (index into appearance.VEHICLE_CLASSES, -1 unknown); for each row of an
    appearance box, the union of the blobs it explained (its carrier; NaN: none) (K, 4),
    that carrier as it was at the appearance pass (`first`, K, 4), and the pass's scale
    (model pixels per frame pixel, K; NaN for motion rows)."""

    boxes: np.ndarray
    areas: np.ndarray
    source: np.ndarray
    score: np.ndarray
    cls: np.ndarray
    carrier: np.ndarray
    first: np.ndarray
    scale: np.ndarray

    def take(self, keep: np.ndarray) -> Fused:
        """The rows where `keep` holds (a mask or indices)."""
        return Fused(self.boxes[keep], self.areas[keep], self.source[keep], self.score[keep],
                     self.cls[keep], self.carrier[keep], self.first[keep], self.scale[keep])

    def riders(self) -> Fused:
        """The appearance rows (those that ride on to the next frame, `follow`)."""
        return self.take(self.source != MOTION)

    def motion(self) -> tuple[np.ndarray, np.ndarray]:
        """The motion rows' boxes and areas."""
        rows = self.source == MOTION
        return self.boxes[rows], self.areas[rows]

    @staticmethod
    def empty() -> Fused:
        return Fused(np.zeros((0, 4)), np.zeros(0), np.zeros(0, int), np.zeros(0),
                     np.zeros(0, int), np.zeros((0, 4)), np.zeros((0, 4)), np.zeros(0))


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
        app.classes[a].astype(int), carriers, carriers.copy(), np.full(len(a), app.scale)))


def _joined(blobs: np.ndarray, areas: np.ndarray, *app: Fused) -> Fused:
    """Motion rows (the blobs) followed by the appearance rows of each of `app`."""
    n = len(blobs)
    cat = lambda name: [getattr(f, name) for f in app]   # noqa: E731
    return Fused(np.concatenate([blobs.reshape(-1, 4), *cat("boxes")]).reshape(-1, 4),
                 np.concatenate([areas, *cat("areas")]),
                 np.concatenate([np.full(n, MOTION), *cat("source")]).astype(int),
                 np.concatenate([np.ones(n), *cat("score")]),
                 np.concatenate([np.full(n, -1), *cat("cls")]).astype(int),
                 np.concatenate([np.full((n, 4), np.nan), *cat("carrier")]),
                 np.concatenate([np.full((n, 4), np.nan), *cat("first")]),
                 np.concatenate([np.full(n, np.nan), *cat("scale")]))


def follow(riders: Fused, blobs: np.ndarray, areas: np.ndarray) -> Fused:
    """This frame's detections between two appearance passes: the appearance boxes of the
    last frame (`riders`, Fused.riders) carried on by this frame's blobs (B, 4) or held
    where they stand, and the blobs no rider takes as motion detections (the module's
    rules)."""
    carried = ~np.isnan(riders.carrier[:, 0])
    keep = np.zeros(len(riders.boxes), dtype=bool)
    boxes, carriers = riders.boxes.copy(), riders.carrier.copy()
    # the riders whose carrier links to blobs, and those blobs (their new carrier)
    rows = np.flatnonzero(carried)
    held = links(riders.carrier[rows], blobs)
    linked = held.any(axis=1)
    rows, held = rows[linked], held[linked]
    new = enclosing_each(blobs, held)
    change = new[:, 2:] / np.maximum(riders.first[rows, 2:], 1e-9)
    ride = ~np.any((change > CARRIER_CHANGE) | (change < 1 / CARRIER_CHANGE), axis=1)
    rows, held, new = rows[ride], held[ride], new[ride]
    boxes[rows] = placed(relative(riders.boxes[rows], riders.carrier[rows]), new)
    carriers[rows] = new
    keep[rows] = True
    taken = held.any(axis=0)   # the blobs the riders ride on
    standing = np.flatnonzero(~carried)
    if len(standing):
        keep[standing] = ~links(blobs, riders.boxes[standing]).any(axis=0)
    k = np.flatnonzero(keep)
    return _joined(blobs[~taken], areas[~taken], Fused(
        boxes[k], np.prod(boxes[k, 2:], axis=1), riders.source[k], riders.score[k],
        riders.cls[k], carriers[k], riders.first[k], riders.scale[k]))


def too_small(boxes: np.ndarray, scale: float) -> np.ndarray:
    """(K,) whether boxes (K, 4) are under SMALL_MODEL_PX on a side at `scale` (model
    pixels per frame pixel): too small for a pass at that scale to place."""
    return boxes[:, 2:].min(axis=1) * scale < SMALL_MODEL_PX


def refreshed(riders: Fused, app: AppearanceBoxes) -> np.ndarray:
    """(K,) whether the pass `app` looks again at each rider (Fused.riders). The whole
    frame's pass looks at the riders it has a box of, sees well enough (SMALL_MODEL_PX) or
    sees as finely as the pass that found them; a tile's pass at the riders wholly inside
    it that the whole frame shows too small (the far vehicles: the tiles' own). The others
    ride on."""
    if app.window is None:
        seen = links(riders.boxes, app.boxes).any(axis=1)
        return seen | ~too_small(riders.boxes, app.scale) | (riders.scale <= app.scale * FINER)
    x, y, w, h = app.window
    b = riders.boxes
    inside = (b[:, 0] >= x) & (b[:, 1] >= y) & (b[:, 0] + b[:, 2] <= x + w) \
        & (b[:, 1] + b[:, 3] <= y + h)
    return inside & too_small(b, app.whole)


def renew(riders: Fused, blobs: np.ndarray, areas: np.ndarray, app: AppearanceBoxes,
          alone_score: float = 0.0) -> Fused:
    """The detections of a frame with an appearance pass `app` (the whole frame or a
    tile): the riders the pass looks at again (`refreshed`) give way to its boxes (`fuse`);
    the others ride on (`follow`), and the pass's boxes that link to them are dropped (the
    rider was measured more finely). A tile's pass gives only the boxes the whole frame
    shows too small: the nearer vehicles are the whole frame's."""
    if app.window is not None:
        app = app.take(too_small(app.boxes, app.whole))
    kept = follow(riders.take(~refreshed(riders, app)), blobs, areas)
    held = kept.riders()
    app = app.take(~links(held.boxes, app.boxes).any(axis=0))
    new = fuse(*kept.motion(), app, alone_score)
    return _joined(*new.motion(), new.riders(), held)
