"""The associator's first stage: fragments. Detections whose centres all fall inside one
confirmed track's predicted box (and in no other) are pieces of one vehicle cut by an
occluder, or several vehicles the track has followed as one blob (a queue far from the
camera, two cars in tandem) that have now come apart.

The gap between the two largest pieces tells them apart (`FragmentJoiner._gap_moved`).
Until it does, the pieces are joined into their union; pieces spanning more than
`split_span` times the track's box are separate vehicles at once. A frame without the
pieces (the blob merged again) forgets the gap, unless the gap has looked like road and the
pieces were seen at most `split_hold_seconds` ago: a detector that flickers between two
vehicles in tandem and their union then still lets the evidence build up.

The stage owns the gap record of every track (`GapColumns`); it returns the record after
this frame instead of writing it, and the tracker keeps it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vtrack.boxes import centre, on_border, overlap_of_smaller, paired_iou
from vtrack.tracking.association import points_in_boxes
from vtrack.tracking.box_size import BoxSizeFilter
from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.columns import Columns

if TYPE_CHECKING:
    from vtrack.tracking.table import TrackTable

# boxes (K, 4) x, y, w, h -> (K,) the share of each that the detector saw change (nan: none)
ChangedShare = Callable[[np.ndarray], np.ndarray]


@dataclass
class GapColumns(Columns):
    """Per track: the gap between two pieces in its box, as first seen."""

    gap_p: np.ndarray      # (N, 2) where a gap between two pieces was first seen
    gap_t: np.ndarray      # (N,) and when (nan: the track's box holds one piece)
    gap_seen: np.ndarray   # (N,) when the track's box last held several pieces
    gap_road: np.ndarray   # (N,) that gap may be road: not body on any frame, not nested

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "gap_p": ((2,), float), "gap_t": ((), float), "gap_seen": ((), float),
        "gap_road": ((), bool)}

    @classmethod
    def new(cls, k: int) -> GapColumns:
        """The rows of k new tracks: no gap seen."""
        return cls(np.full((k, 2), np.nan), np.full(k, np.nan), np.full(k, np.nan),
                   np.zeros(k, dtype=bool))

    def warp(self, m: np.ndarray) -> None:
        """Move the gaps with the camera (m (2, 3): p' = A p + b)."""
        self.gap_p = self.gap_p @ m[:, :2].T + m[:, 2]


@dataclass
class Fragments:
    """The detections after joining the pieces of each track's vehicle."""

    centers: np.ndarray    # (D', 2)
    boxes: np.ndarray      # (D', 4)
    split: np.ndarray      # (N,) tracks whose box held several vehicles
    gaps: GapColumns       # the gap record after this frame
    origin: np.ndarray     # (D',) the input detection each row is (a joined one: its first)
    whole: np.ndarray      # (D',) the row is a whole box (provenance.py): never joined


class FragmentJoiner:
    """Joins or splits the pieces in each confirmed track's box (module docstring)."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int) -> None:
        self.cfg = cfg
        self.width, self.height = width, height
        self.size_gate = BoxSizeFilter.from_config(cfg)

    def join(self, tracks: TrackTable, gaps: GapColumns, track_boxes: np.ndarray, t: float,
             centers: np.ndarray, boxes: np.ndarray, changed: ChangedShare | None,
             whole: np.ndarray | None = None) -> Fragments:
        """The detections with the pieces of each track's vehicle joined, the tracks whose
        box held several vehicles and the gap record after this frame (`gaps` is not
        changed). Only motion-only detections are pieces: `whole` (D,) marks whole boxes
        (provenance.py), which are vehicles and never joined."""
        cfg = self.cfg
        gaps = gaps.copy()
        split = np.zeros(len(tracks), dtype=bool)
        conf = tracks.confirmed
        held = np.zeros(len(tracks), dtype=bool)
        origin = np.arange(len(centers))
        whole = np.zeros(len(centers), dtype=bool) if whole is None else whole
        blobs = np.flatnonzero(~whole)
        if len(conf) and len(blobs) >= 2:
            bi, di = points_in_boxes(centers[blobs], track_boxes[conf], cfg.box_candidates)
            di = blobs[di]
            claims = np.bincount(di, minlength=len(centers))
            ok = claims[di] == 1
            bi, di = bi[ok], di[ok]
            per_box = np.bincount(bi, minlength=len(conf))
            keep = np.ones(len(centers), dtype=bool)
            boxes = boxes.copy()
            for b in np.flatnonzero(per_box >= 2):
                track, parts = conf[b], di[bi == b]
                if cfg.whole_piece and self._one_is_whole(tracks, track, track_boxes[track],
                                                          boxes[parts]):
                    continue
                held[track] = True
                x0 = boxes[parts, :2].min(axis=0)
                x1 = (boxes[parts, :2] + boxes[parts, 2:]).max(axis=0)
                apart = np.any(x1 - x0 > cfg.split_span * tracks.size[track])
                if apart or self._gap_moved(tracks, gaps, track, t, boxes[parts], changed):
                    split[track] = True
                    continue
                boxes[parts[0]] = [*x0, *(x1 - x0)]
                keep[parts[1:]] = False
            boxes, origin = boxes[keep], origin[keep]
            centers = centre(boxes)
        gaps.gap_seen[held] = t
        holding = gaps.gap_road & (t - gaps.gap_seen <= cfg.split_hold_seconds + 1e-9)
        gaps.gap_t[(~held & ~holding) | split] = np.nan
        return Fragments(centers, boxes, split, gaps, origin, whole[origin])

    def _one_is_whole(self, tracks: TrackTable, track: int, predicted: np.ndarray,
                      pieces: np.ndarray) -> bool:
        """Whether one of `pieces` (x, y, w, h) is by itself the track's vehicle where it
        is predicted (`predicted`, x, y, w, h): both its sides within the size gate
        (box_size.py), none cut by the image border, and IoU with the predicted box at least
        `blob_fit_iou`. That piece is the vehicle and the others are other vehicles, not
        its parts (whole boxes, as a good detector gives, of vehicles that overlap)."""
        k = np.full(len(pieces), track)
        fits = self.size_gate.in_gate(tracks.s[k], tracks.Ps[k], pieces[:, 2:])
        cut = on_border(pieces, self.width, self.height).any(axis=(1, 2))
        there = paired_iou(pieces, predicted[None]) >= self.cfg.blob_fit_iou
        return bool(np.any(fits.all(axis=1) & ~cut & there))

    def _gap_moved(self, tracks: TrackTable, gaps: GapColumns, track: int, t: float,
                   pieces: np.ndarray, changed: ChangedShare | None) -> bool:
        """Whether the gap between the two largest `pieces` (x, y, w, h) shows several
        vehicles; records it in `gaps` when it is new.

        - An occluder is static: its gap stays where it first appeared while the vehicle
          moves on. The gap between two vehicles moves with them. Once the track has moved
          `split_evidence` box scales since the gap appeared, a gap that followed it by
          `gap_follow_share` of that or more shows several vehicles.
        - With the detector's changed map (vision/changed.py), the gap's pixels tell as
          well, once the vehicle has moved its own length since its first detection
          (`_moved_its_length`). A gap that MOG2 labelled foreground or shadow for at least
          `gap_changed_share` of it is body: one vehicle seen in two pieces, never split.
          A gap of road that has moved with the track by `gap_follow_share` of its travel
          or more, on a frame after the one it appeared in, shows two vehicles at once.
          Pieces that overlap on both axes have no gap to read; a piece lying within the
          other (`nested_share`) is a part of it (a car's windows in its body), and its
          record is not held through a merged frame (`join`)."""
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
        if np.isnan(gaps.gap_t[track]):
            gaps.gap_p[track], gaps.gap_t[track] = gap, t
            nested = overlap_of_smaller(a, b[None])[0] >= cfg.nested_share
            gaps.gap_road[track] = changed is not None and not body and not nested
            return False
        if body:
            gaps.gap_road[track] = False
            return False
        moved = np.hypot(*(gap - gaps.gap_p[track]))
        travelled = np.hypot(*tracks.x[track, 2:4]) * (t - gaps.gap_t[track])
        follows = moved >= cfg.gap_follow_share * travelled
        if not np.isnan(share) and gaps.gap_road[track] and follows:
            return True
        if travelled < cfg.split_evidence * tracks.scale[track]:
            return False
        return bool(follows)


def _moved_its_length(tracks: TrackTable, track: int) -> bool:
    """Whether the vehicle has moved its own length along its way since its first
    detection. Until then the road it covers may be road it stood on, learnt into MOG2's
    background with it (a queue, a vehicle in view from the start), and a slow vehicle's
    even paint looks unchanged inside it: MOG2's labels there cannot tell body from road."""
    first = (tracks.origin[track, :2] + tracks.origin[track, 2:]) / 2
    way = tracks.x[track, :2] - first
    travelled = float(np.hypot(*way))
    return travelled > 0 and travelled >= float(np.abs(way) @ tracks.size[track]) / travelled
