"""The associator: which detection updates which track, in four stages run in one order.

1. fragments: detections that all lie in one confirmed track's predicted box are pieces of
   one vehicle (joined) or several vehicles that came apart (the track is marked split),
   told apart by the gap between them: its motion and, with the detector's changed map,
   whether it is road or body;
2. gate and assign: Mahalanobis gating on k-d-tree candidates, optimal assignment per
   connected group (vtrack.tracking.association);
3. shared blobs: a detection holding the predicted centres of several confirmed tracks is a
   duplicate (the younger tracks are deleted) or a merge (the tracks coast);
4. re-acquisition: a track left without a detection takes a left-over one inside its box.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vtrack.boxes import intersection, overlap_of_smaller, paired_iou
from vtrack.tracking.association import assign, gated_pairs, nearest_pairs
from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.measurements import nested_centre
from vtrack.tracking.table import TrackTable


NESTED = 0.9          # a piece this much inside the other is a part of it (no gap)
SMALL_IN_BLOB = 0.25  # a track box under this share of a shared blob is not its duplicate

# boxes (K, 4) x, y, w, h -> (K,) the share of each that the detector saw change (nan: none)
ChangedShare = Callable[[np.ndarray], np.ndarray]


def detection_sigma(cfg: TrackerConfig, scale: np.ndarray) -> np.ndarray:
    """Std (px) of a detected centre for boxes of scale `scale` (px): scale-free, >= 0.5."""
    return np.maximum(cfg.detection_sigma * scale, 0.5)


@dataclass
class Association:
    """The outcome of one frame's association."""

    centers: np.ndarray      # (D, 2) detections after joining fragments
    boxes: np.ndarray        # (D, 4)
    tracks: np.ndarray       # (K,) track indices ...
    detections: np.ndarray   # (K,) ... and the detection each takes
    consumed: np.ndarray     # detections that are merged blobs (they start no track)
    split: np.ndarray        # (N,) tracks whose box held several vehicles
    duplicates: np.ndarray   # tracks following the same vehicle as an older track


class Associator:
    """Runs the association stages for one frame (see the module docstring)."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int) -> None:
        self.cfg = cfg
        self.width, self.height = width, height
        self.gate = -2.0 * math.log1p(-cfg.gate_probability)  # chi-square quantile, 2 dof

    def associate(self, tracks: TrackTable, t: float, centers: np.ndarray, boxes: np.ndarray,
                  changed: ChangedShare | None = None) -> Association:
        """Pair this frame's detections with the predicted tracks; `changed` (boxes (K, 4)
        -> (K,)) is the share of each box that the detector saw change, when it has one."""
        cfg = self.cfg
        track_boxes = tracks.boxes(self.width, self.height)
        centers, boxes, split = self._join_fragments(tracks, track_boxes, t, centers, boxes,
                                                     changed)
        size, scale = tracks.size, tracks.scale
        sigma = detection_sigma(cfg, scale)
        ti, di, cost = gated_pairs(
            tracks.x[:, :2], tracks.P[:, :2, :2], centers, self.gate, cfg.max_gate * scale,
            lambda trk, det: nested_centre(tracks.x[trk, :2], size[trk], boxes[det],
                                           sigma[trk, None]))
        # A vehicle's detection overlaps its predicted box (the gate alone, in box scales,
        # would let a coasting track with a large box jump to a neighbour).
        touch = intersection(track_boxes[ti], boxes[di]) > 0
        ti, di, cost = ti[touch], di[touch], cost[touch]
        mt, md = assign(ti, di, cost, len(tracks), len(centers))
        mt, md, consumed, duplicates = _resolve_shared(tracks, track_boxes, mt, md, boxes)
        mt, md = _reacquire(tracks, track_boxes, mt, md, consumed, duplicates, centers, boxes)
        return Association(centers, boxes, mt, md, consumed, split, duplicates)

    def _join_fragments(self, tracks: TrackTable, track_boxes: np.ndarray, t: float,
                        centers: np.ndarray, boxes: np.ndarray, changed: ChangedShare | None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Detections whose centres all fall inside one confirmed track's predicted box (and
        in no other) are pieces of one vehicle cut by an occluder, or several vehicles the
        track has followed as one blob (a queue far from the camera, two cars in tandem)
        that have now come apart.

        The gap between the two largest pieces tells them apart (`_gap_moved`). Until it
        does, the pieces are joined into their union; pieces spanning more than 1.2 times
        the track's box are separate vehicles at once. A frame without the pieces (the blob
        merged again) forgets the gap, unless the gap has looked like road and the pieces
        were seen at most `split_hold_seconds` ago: a detector that flickers between two
        vehicles in tandem and their union then still lets the evidence build up.
        Returns the detections and which tracks were split; records the gaps in the table.
        """
        split = np.zeros(len(tracks), dtype=bool)
        conf = tracks.confirmed
        held = np.zeros(len(tracks), dtype=bool)
        if len(conf) and len(centers) >= 2:
            bi, di = points_in_boxes(centers, track_boxes[conf])
            claims = np.bincount(di, minlength=len(centers))
            ok = claims[di] == 1
            bi, di = bi[ok], di[ok]
            per_box = np.bincount(bi, minlength=len(conf))
            keep = np.ones(len(centers), dtype=bool)
            boxes = boxes.copy()
            for b in np.flatnonzero(per_box >= 2):
                track, parts = conf[b], di[bi == b]
                held[track] = True
                x0 = boxes[parts, :2].min(axis=0)
                x1 = (boxes[parts, :2] + boxes[parts, 2:]).max(axis=0)
                apart = np.any(x1 - x0 > 1.2 * tracks.size[track])
                if apart or self._gap_moved(tracks, track, t, boxes[parts], changed):
                    split[track] = True
                    continue
                boxes[parts[0]] = [*x0, *(x1 - x0)]
                keep[parts[1:]] = False
            boxes = boxes[keep]
            centers = boxes[:, :2] + boxes[:, 2:] / 2
        tracks.gap_seen[held] = t
        holding = tracks.gap_road & (t - tracks.gap_seen <= self.cfg.split_hold_seconds + 1e-9)
        tracks.gap_t[(~held & ~holding) | split] = np.nan
        return centers, boxes, split

    def _gap_moved(self, tracks: TrackTable, track: int, t: float, pieces: np.ndarray,
                   changed: ChangedShare | None) -> bool:
        """Whether the gap between the two largest `pieces` (x, y, w, h) shows several
        vehicles; records it when it is new.

        - An occluder is static: its gap stays where it first appeared while the vehicle
          moves on. The gap between two vehicles moves with them. Once the track has moved
          `split_evidence` box scales since the gap appeared, a gap that followed it by
          half that or more shows several vehicles.
        - With the detector's changed map (vision/changed.py), the gap's pixels tell as
          well, once the vehicle has moved its own length since its first detection
          (`_moved_its_length`). A gap that MOG2 labelled foreground or shadow for at least
          `gap_changed_share` of it is body: one vehicle seen in two pieces, never split.
          A gap of road that has moved with the track by half its travel or more, on a
          frame after the one it appeared in, shows two vehicles at once. Pieces that
          overlap on both axes have no gap to read; a piece lying within the other
          (`NESTED`) is a part of it (a car's windows in its body), and its record is
          not held through a merged frame (`_join_fragments`)."""
        cfg = self.cfg
        a, b = pieces[np.argsort(pieces[:, 2] * pieces[:, 3])[-2:]]
        lo = np.minimum(a[:2] + a[2:], b[:2] + b[2:])   # per axis: the facing edges when the
        hi = np.maximum(a[:2], b[:2])                   # pieces are apart, else their overlap
        gap = (lo + hi) / 2
        share = np.nan
        if changed is not None and np.any(lo < hi) and _moved_its_length(tracks, track):
            corner = np.minimum(lo, hi)
            share = float(changed(np.array([[*corner, *(np.maximum(lo, hi) - corner)]]))[0])
        body = bool(share >= cfg.gap_changed_share)   # nan: not known
        if np.isnan(tracks.gap_t[track]):
            tracks.gap_p[track], tracks.gap_t[track] = gap, t
            nested = overlap_of_smaller(a, b[None])[0] >= NESTED
            tracks.gap_road[track] = changed is not None and not body and not nested
            return False
        if body:
            tracks.gap_road[track] = False
            return False
        moved = np.hypot(*(gap - tracks.gap_p[track]))
        travelled = np.hypot(*tracks.x[track, 2:4]) * (t - tracks.gap_t[track])
        if not np.isnan(share) and tracks.gap_road[track] and moved >= 0.5 * travelled:
            return True
        if travelled < cfg.split_evidence * tracks.scale[track]:
            return False
        return bool(moved >= 0.5 * travelled)


def _moved_its_length(tracks: TrackTable, track: int) -> bool:
    """Whether the vehicle has moved its own length along its way since its first
    detection. Until then the road it covers may be road it stood on, learnt into MOG2's
    background with it (a queue, a vehicle in view from the start), and a slow vehicle's
    even paint looks unchanged inside it: MOG2's labels there cannot tell body from road."""
    first = (tracks.origin[track, :2] + tracks.origin[track, 2:]) / 2
    way = tracks.x[track, :2] - first
    travelled = float(np.hypot(*way))
    return travelled > 0 and travelled >= float(np.abs(way) @ tracks.size[track]) / travelled


def _resolve_shared(tracks: TrackTable, track_boxes: np.ndarray, mt: np.ndarray,
                    md: np.ndarray, boxes: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Detections whose box holds the predicted centres of two or more confirmed tracks.

    A standing track (lifecycle.py) among moving ones is being passed: it is left out.
    If those tracks' boxes largely overlap (the intersection covers over half of the smaller
    box), they follow one vehicle: the oldest track takes the detection and the younger ones
    are duplicates; but where the oldest's box is under a quarter of the blob and another's
    is the blob (IoU >= 0.5), the oldest follows a smaller vehicle seen over a larger one (a
    car beside a truck): the larger vehicle's track takes the blob and the others coast,
    none deleted. Otherwise the detection is a merged blob of several vehicles: its
    centroid belongs to none of them, so those tracks coast instead of being pulled toward
    the middle, and the blob is consumed (it starts no track).
    Returns the pairs, the consumed detections and the duplicate tracks.
    """
    consumed: list[int] = []
    duplicates: list[np.ndarray] = []
    conf = tracks.confirmed
    none = np.zeros(0, dtype=int)
    if len(boxes) == 0 or len(conf) < 2:
        return mt, md, none, none
    bi, pi = points_in_boxes(tracks.x[conf, :2], boxes)
    # A track whose centre lies in more than one detection box has a detection of its own.
    alone = np.bincount(pi, minlength=len(conf))[pi] == 1
    bi, pi = bi[alone], pi[alone]
    for d in np.flatnonzero(np.bincount(bi, minlength=len(boxes)) >= 2):
        held = conf[pi[bi == d]]
        # A moving vehicle passes a standing one: the standing track neither takes the
        # blob nor makes the moving one its duplicate; one moving track takes it.
        still = tracks.standing[held]
        if still.any() and not still.all():
            passed = np.isin(mt, held[still]) & (md == d)
            mt, md = mt[~passed], md[~passed]
            held = held[~still]
            if len(held) == 1:
                if held[0] not in mt and d not in md:
                    mt, md = np.append(mt, held[0]), np.append(md, d)
                continue
        taken = np.isin(mt, held) | (md == d)
        mt, md = mt[~taken], md[~taken]
        oldest = held[np.argmin(tracks.uid[held])]
        others = held[held != oldest]
        if np.all(overlap_of_smaller(track_boxes[oldest], track_boxes[others]) > 0.5):
            fitting = _fitting_track(track_boxes[held], track_boxes[oldest], boxes[d])
            if fitting is None:
                mt, md = np.append(mt, oldest), np.append(md, d)
                duplicates.append(others)
            else:  # a small vehicle seen over a large one: the large one's blob
                mt, md = np.append(mt, held[fitting]), np.append(md, d)
        else:
            consumed.append(int(d))
    dup = np.concatenate(duplicates) if duplicates else none
    return mt, md, np.array(consumed, dtype=int), dup


def _fitting_track(held_boxes: np.ndarray, oldest_box: np.ndarray, blob: np.ndarray
                   ) -> int | None:
    """Index into `held_boxes` of the track whose box is the blob `blob` (IoU >= 0.5, the
    best), when the oldest track's box covers under a quarter of the blob; else None."""
    if oldest_box[2] * oldest_box[3] >= SMALL_IN_BLOB * blob[2] * blob[3]:
        return None
    fit = paired_iou(held_boxes, blob[None])
    return int(np.argmax(fit)) if fit.max() >= 0.5 else None


def _reacquire(tracks: TrackTable, track_boxes: np.ndarray, mt: np.ndarray, md: np.ndarray,
               consumed: np.ndarray, duplicates: np.ndarray, centers: np.ndarray,
               boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A track left without a detection takes a left-over detection whose centre lies
    inside its predicted box (nearest first) and whose area is at most twice the box's.

    A track that coasted on a prediction spoilt by partial detections (an occluder) can
    drift out of its own gate while its vehicle is plainly inside its box; without this stage
    the detection could neither update the track nor start a new one. A tentative track
    takes part too: when the visible part of a vehicle jumps (entering behind an occluder),
    a second track on the same vehicle would otherwise start beside it."""
    waiting = np.ones(len(tracks), dtype=bool)
    waiting[duplicates] = False
    waiting[mt] = False
    lost = np.flatnonzero(waiting)
    if len(lost) == 0:
        return mt, md
    free = np.setdiff1d(np.arange(len(centers)), np.concatenate([md, consumed]))
    if len(free) == 0:
        return mt, md
    bi, pi = points_in_boxes(centers[free], track_boxes[lost])
    # ... and is not a blob far larger than the vehicle (a merge of several).
    area = boxes[free[pi], 2] * boxes[free[pi], 3]
    ok = area <= 2.0 * track_boxes[lost[bi], 2] * track_boxes[lost[bi], 3]
    bi, pi = bi[ok], pi[ok]
    if len(bi) == 0:
        return mt, md
    dist = np.linalg.norm(centers[free[pi]] - tracks.x[lost[bi], :2], axis=1)
    rt, rd = assign(bi, pi, dist, len(lost), len(free))
    return np.concatenate([mt, lost[rt]]), np.concatenate([md, free[rd]])


def points_in_boxes(points: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(box, point) index pairs with the point inside the box (x, y, w, h), among each box's 8
    nearest points (a box holds a few vehicle centres at most)."""
    centre = boxes[:, :2] + boxes[:, 2:] / 2
    radius = float(np.hypot(boxes[:, 2], boxes[:, 3]).max()) / 2 + 1e-9 if len(boxes) else 0.0
    bi, pi = nearest_pairs(centre, points, radius)
    inside = np.all(np.abs(points[pi] - centre[bi]) <= boxes[bi, 2:] / 2, axis=1)
    return bi[inside], pi[inside]
