"""The associator: which detection updates which track, in four named stages run in one
order. It changes nothing: it returns its decisions (pairs, consumed blobs, split tracks,
duplicates) and the fragment stage's gap record after this frame.

1. fragments (fragments.py): detections that all lie in one confirmed track's predicted box
   are pieces of one vehicle (joined) or several vehicles that came apart (the track is
   marked split), told apart by the gap between them: its motion and, with the detector's
   changed map, whether it is road or body;
2. gate and assign: Mahalanobis gating on k-d-tree candidates, optimal assignment per
   connected group (vtrack.tracking.association); a whole box (provenance.py) is measured
   as the vehicle: its centre, and its sides' Mahalanobis distance from the track's size
   in the cost (a side the border cuts counts only where it is larger than the track's);
   whole boxes are assigned first, blobs to the tracks left;
3. shared blobs (`resolve_shared`): a detection holding the predicted centres of several
   confirmed tracks is a duplicate (the younger tracks are deleted) or a merge (the tracks
   coast); a whole box (provenance.py) is never a merge;
4. re-acquisition (`reacquire`): a track left without a detection takes a left-over one
   inside its box.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vtrack.boxes import intersection, on_border, overlap_of_smaller, paired_iou
from vtrack.tracking.box_size import BoxSizeFilter
from vtrack.tracking.association import assign, gated_pairs, points_in_boxes
from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.fragments import ChangedShare, FragmentJoiner, GapColumns
from vtrack.tracking.measurements import detection_sigma, nested_centre
from vtrack.tracking.table import TrackTable

__all__ = ["Association", "Associator", "ChangedShare", "detection_sigma"]


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
    patient: np.ndarray      # (len(duplicates),) ... on a whole box (provenance.py)
    gaps: GapColumns         # the fragment stage's gap record after this frame
    origin: np.ndarray       # (D,) the input detection each of `boxes` is (fragments.py)
    whole: np.ndarray        # (D,) each of `boxes` is a whole box (provenance.py)
    track_boxes: np.ndarray  # (N, 4) every track's predicted box, clipped to the image


class Associator:
    """Runs the association stages for one frame (see the module docstring)."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int) -> None:
        self.cfg = cfg
        self.width, self.height = width, height
        self.gate = -2.0 * math.log1p(-cfg.gate_probability)  # chi-square quantile, 2 dof
        self.fragments = FragmentJoiner(cfg, width, height)
        self.size = BoxSizeFilter.from_config(cfg)

    def associate(self, tracks: TrackTable, gaps: GapColumns, t: float, centers: np.ndarray,
                  boxes: np.ndarray, changed: ChangedShare | None = None,
                  whole: np.ndarray | None = None) -> Association:
        """Pair this frame's detections with the predicted tracks; `gaps` is the fragment
        stage's record before this frame; `changed` (boxes (K, 4) -> (K,)) is the share of
        each box that the detector saw change, when it has one; `whole` (D,) marks the
        whole boxes (provenance.py; None: all are blobs)."""
        cfg = self.cfg
        track_boxes = tracks.boxes(self.width, self.height)
        f = self.fragments.join(tracks, gaps, track_boxes, t, centers, boxes, changed, whole)
        centers, boxes = f.centers, f.boxes
        size, scale = tracks.size, tracks.scale
        sigma = detection_sigma(cfg, scale)
        cut = on_border(boxes, self.width, self.height).any(axis=2)
        vehicle = f.whole & ~cut.any(axis=1)   # whole boxes that show the whole vehicle

        def measured(trk: np.ndarray, det: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            z, var = nested_centre(tracks.x[trk, :2], size[trk], boxes[det], sigma[trk, None])
            own = vehicle[det]
            z[own] = centers[det[own]]
            var[own] = sigma[trk[own], None] ** 2
            return z, var

        ti, di, cost = gated_pairs(tracks.x[:, :2], tracks.P[:, :2, :2], centers, self.gate,
                                   cfg.max_gate * scale, measured, cfg.gate_candidates)
        w = f.whole[di]
        if w.any():   # a whole box's sides against the track's size, in the cost
            cost = cost.copy()
            cost[w] += self.size.d2(tracks.s[ti[w]], tracks.Ps[ti[w]], boxes[di[w], 2:],
                                    cut[di[w]])

        # A vehicle's detection overlaps its predicted box (the gate alone, in box scales,
        # would let a coasting track with a large box jump to a neighbour).
        touch = intersection(track_boxes[ti], boxes[di]) > 0
        ti, di, cost = ti[touch], di[touch], cost[touch]
        mt, md = assign_whole_first(ti, di, cost, f.whole[di], len(tracks), len(centers))
        mt, md, consumed, duplicates, patient = resolve_shared(cfg, tracks, track_boxes, mt,
                                                               md, boxes, f.whole)
        mt, md = reacquire(cfg, tracks, track_boxes, mt, md, consumed, duplicates, centers,
                           boxes)
        return Association(centers, boxes, mt, md, consumed, f.split, duplicates, patient,
                           f.gaps, f.origin, f.whole, track_boxes)


def assign_whole_first(ti: np.ndarray, di: np.ndarray, cost: np.ndarray, whole: np.ndarray,
                       n_tracks: int, n_dets: int) -> tuple[np.ndarray, np.ndarray]:
    """The assignment (association.assign) of the gated pairs in two rounds: the whole boxes
    first (provenance.py: a vehicle's own box, whose sides add to its cost), then the blobs
    to the tracks left (a blob's cost has no size term, so in one round a piece or a merge
    beside a vehicle's whole box would win it for its centre alone). `whole` (len(ti),)
    marks the pairs on whole boxes."""
    wt, wd = assign(ti[whole], di[whole], cost[whole], n_tracks, n_dets)
    rest = ~whole & ~np.isin(ti, wt)
    bt, bd = assign(ti[rest], di[rest], cost[rest], n_tracks, n_dets)
    return np.concatenate([wt, bt]), np.concatenate([wd, bd])


def resolve_shared(cfg: TrackerConfig, tracks: TrackTable, track_boxes: np.ndarray,
                   mt: np.ndarray, md: np.ndarray, boxes: np.ndarray,
                   whole: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Detections whose box holds the predicted centres of two or more confirmed tracks.

    A standing track (lifecycle.py) among moving ones is being passed: it is left out.
    If those tracks' boxes largely overlap (the intersection covers over `duplicate_overlap`
    of the smaller box; for a whole box, their IoU is over it), they follow one vehicle: the oldest track takes the detection and
    the younger ones are duplicates; but where the oldest's box is under `small_in_blob` of
    the blob and another's is the blob (IoU >= `blob_fit_iou`), the oldest follows a smaller
    vehicle seen over a larger one (a car beside a truck): the larger vehicle's track takes
    the blob and the others coast, none deleted. Otherwise the detection is a merged blob of several vehicles: its
    centroid belongs to none of them, so those tracks coast instead of being pulled toward
    the middle, and the blob is consumed (it starts no track). A whole box (`whole`,
    provenance.py) is one vehicle, never a merge: the assignment's pairs stand.
    Returns the pairs, the consumed detections, the duplicate tracks and which of those
    shared a whole box (patient: deleted after `whole_duplicate_seconds`).
    """
    consumed: list[int] = []
    duplicates: list[np.ndarray] = []
    patient: list[np.ndarray] = []
    conf = tracks.confirmed
    none = np.zeros(0, dtype=int)
    if len(boxes) == 0 or len(conf) < 2:
        return mt, md, none, none, np.zeros(0, dtype=bool)
    whole = np.zeros(len(boxes), dtype=bool) if whole is None else whole
    bi, pi = points_in_boxes(tracks.x[conf, :2], boxes, cfg.box_candidates)
    # A track whose centre lies in more than one detection box has a detection of its own.
    alone = np.bincount(pi, minlength=len(conf))[pi] == 1
    bi, pi = bi[alone], pi[alone]
    for d in np.flatnonzero(np.bincount(bi, minlength=len(boxes)) >= 2):
        held = conf[pi[bi == d]]
        # A moving vehicle passes a standing one: the standing track neither takes the
        # blob nor makes the moving one its duplicate; one moving track takes it. (Their
        # whole boxes are their own: the assignment tells them apart.)
        still = tracks.standing[held]
        if still.any() and not still.all() and not whole[d]:
            passed = np.isin(mt, held[still]) & (md == d)
            mt, md = mt[~passed], md[~passed]
            held = held[~still]
            if len(held) == 1:
                if held[0] not in mt and d not in md:
                    mt, md = np.append(mt, held[0]), np.append(md, d)
                continue
        oldest = held[np.argmin(tracks.uid[held])]
        others = held[held != oldest]
        # tracks on one vehicle: boxes that largely overlap (a blob's tracks), or, on a
        # whole box, boxes alike (IoU): a whole box over a smaller one is a vehicle in front
        # of another
        overlap = (paired_iou(track_boxes[others], track_boxes[oldest][None]) if whole[d]
                   else overlap_of_smaller(track_boxes[oldest], track_boxes[others]))
        same = np.all(overlap > cfg.duplicate_overlap)
        if whole[d] and not same:
            continue   # vehicles whose whole boxes overlap: the assignment stands
        taken = np.isin(mt, held) | (md == d)
        mt, md = mt[~taken], md[~taken]
        if same:
            fitting = _fitting_track(cfg, track_boxes[held], track_boxes[oldest], boxes[d])
            if fitting is None:
                mt, md = np.append(mt, oldest), np.append(md, d)
                duplicates.append(others)
                patient.append(np.full(len(others), bool(whole[d])))
            else:  # a small vehicle seen over a large one: the large one's blob
                mt, md = np.append(mt, held[fitting]), np.append(md, d)
        else:
            consumed.append(int(d))
    dup = np.concatenate(duplicates) if duplicates else none
    wait = np.concatenate(patient) if patient else np.zeros(0, dtype=bool)
    return mt, md, np.array(consumed, dtype=int), dup, wait


def _fitting_track(cfg: TrackerConfig, held_boxes: np.ndarray, oldest_box: np.ndarray,
                   blob: np.ndarray) -> int | None:
    """Index into `held_boxes` of the track whose box is the blob `blob` (IoU >=
    `blob_fit_iou`, the best), when the oldest track's box covers under `small_in_blob` of
    the blob; else None."""
    if oldest_box[2] * oldest_box[3] >= cfg.small_in_blob * blob[2] * blob[3]:
        return None
    fit = paired_iou(held_boxes, blob[None])
    return int(np.argmax(fit)) if fit.max() >= cfg.blob_fit_iou else None


def reacquire(cfg: TrackerConfig, tracks: TrackTable, track_boxes: np.ndarray,
              mt: np.ndarray, md: np.ndarray, consumed: np.ndarray, duplicates: np.ndarray,
              centers: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A track left without a detection takes a left-over detection whose centre lies
    inside its predicted box (nearest first) and whose area is at most `reacquire_area`
    times the box's.

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
    bi, pi = points_in_boxes(centers[free], track_boxes[lost], cfg.box_candidates)
    # ... and is not a blob far larger than the vehicle (a merge of several).
    area = boxes[free[pi], 2] * boxes[free[pi], 3]
    ok = area <= cfg.reacquire_area * track_boxes[lost[bi], 2] * track_boxes[lost[bi], 3]
    bi, pi = bi[ok], pi[ok]
    if len(bi) == 0:
        return mt, md
    dist = np.linalg.norm(centers[free[pi]] - tracks.x[lost[bi], :2], axis=1)
    rt, rd = assign(bi, pi, dist, len(lost), len(free))
    return np.concatenate([mt, lost[rt]]), np.concatenate([md, free[rd]])
