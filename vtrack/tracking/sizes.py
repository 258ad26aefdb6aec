"""The size role: every track's box size, behind one `update()` per frame.

It holds the box size filter (box_size.py) and the scene's scale field (scale_field.py).
`update` runs its heuristics in this order, each reading what the one before left:

1. the expected motion of the box's edges (`rates`: perspective growth plus the filter's
   rates) tells a partial view behind a static occluder (`anchored`);
2. the vehicle's own size (`own_size`: the median of its last detections, carried along
   the scale field; not from an anchored view), then this detection joins that memory
   (`remember_size`) unless cut by the image border or anchored;
3. a receding vehicle detected centred inside its predicted box (`shrunk`) shows the whole
   vehicle: its size starts again from it; so does a whole box (one the appearance model
   drew, provenance.py), which is never an anchored partial view either; with
   `shrink_unexplained`, so does any smaller detection that nothing shows to be a partial
   view (`_unexplained`);
4. the size filter's gated update with those three (BoxSizeFilter.update), which returns
   the sides that showed the whole vehicle;
5. a whole detection of a confirmed track that overlaps no other track's box teaches the
   scale field (`_learn_scale`);
6. a track whose box held several vehicles (a split blob) starts its size again from its
   piece, keeping its rates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from scipy.spatial import cKDTree

from vtrack.boxes import centre, intersection, scale
from vtrack.tracking.box_size import (OWN, BoxSizeFilter, anchored, own_size,
                                      remember_size)
from vtrack.tracking.columns import Columns, warp_scale
from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.measurements import border_cut, detection_sigma, shrunk
from vtrack.tracking.provenance import near_border
from vtrack.tracking.scale_field import ScaleField

if TYPE_CHECKING:
    from vtrack.tracking.table import TrackTable


@dataclass
class SizeColumns(Columns):
    """Per track: the box size filter's state, the own-size memory, the scale field's
    reference box."""

    s: np.ndarray          # (N, 4) [ln w, ln h, d ln w/dt, d ln h/dt] of the box (box_size.py)
    Ps: np.ndarray         # (N, 4, 4) its covariance
    mismatch_t: np.ndarray     # (N, 2) since when detections disagree with the size
    mismatch_sign: np.ndarray  # (N, 2) in which direction (+1 larger, -1 smaller, 0 none)
    own: np.ndarray        # (N, OWN, 2) ln((w, h) / k) of the last detections (nan: none)
    ref_p: np.ndarray      # (N, 2) a whole-vehicle box's centre kept for the scale field
    ref_s: np.ndarray      # (N,) and its scale (nan: none yet)

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "s": ((4,), float), "Ps": ((4, 4), float), "mismatch_t": ((2,), float),
        "mismatch_sign": ((2,), float), "own": ((OWN, 2), float), "ref_p": ((2,), float),
        "ref_s": ((), float)}

    def warp(self, m: np.ndarray) -> None:
        """Sizes scale by sqrt|det A| (their logs shift); the scale field's reference
        stays where it was seen."""
        scale = warp_scale(m)
        self.s[:, :2] += np.log(scale)
        self.own += np.log(scale)


@dataclass
class SizeUpdate:
    """What the size role decided for the detected boxes (K) of tracks idx."""

    whole: np.ndarray        # (K, 2) the sides that showed the whole vehicle
    shows_whole: np.ndarray  # (K,) every side whole, and not a piece of a split blob
    size: np.ndarray         # (K, 2) the predicted size the detections were compared with
    size_var: np.ndarray     # (K, 2) its variance, px^2
    cut: np.ndarray          # (K, 2, 2) the edges on the image border (border_cut)


class Sizes:
    """The size role (module docstring)."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int) -> None:
        self.cfg = cfg
        self.width, self.height = width, height
        self.filter = BoxSizeFilter.from_config(cfg)
        self.field = ScaleField(width, height)

    def initial(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(s, Ps) of new tracks from their first boxes (K, 4)."""
        return self.filter.initial(boxes[:, 2:], self.cfg.init_size_rate_sigma)

    def new(self, boxes: np.ndarray) -> SizeColumns:
        """The rows of tracks born on boxes (K, 4): their size from the box, its rates
        unknown, no mismatch, no own size, no reference."""
        k = len(boxes)
        s0, Ps0 = self.initial(boxes)
        return SizeColumns(s0, Ps0, np.full((k, 2), np.nan), np.zeros((k, 2)),
                           np.full((k, OWN, 2), np.nan), np.zeros((k, 2)), np.full(k, np.nan))

    def growth(self, tracks: TrackTable, idx: np.ndarray | slice = slice(None)
               ) -> np.ndarray:
        """d ln s/dt (K,) that the scene's perspective gives tracks idx's motion (0 without
        the scale field)."""
        if not self.cfg.scale_field:
            return np.zeros(len(tracks.x[idx]))
        return self.field.log_rate(tracks.x[idx, :2], tracks.x[idx, 2:4])

    def predict(self, tracks: TrackTable, dt: float, growth: np.ndarray) -> None:
        """Propagate every track's size over dt (s) with its perspective growth (K,)."""
        tracks.s, tracks.Ps = self.filter.predict(tracks.s, tracks.Ps, dt, growth)

    def rates(self, tracks: TrackTable, idx: np.ndarray) -> np.ndarray:
        """d(w, h)/dt (px/s) of tracks idx: the growth the scene's perspective gives their
        motion plus the size filter's own rates."""
        return tracks.size[idx] * (self.growth(tracks, idx)[:, None] + tracks.s[idx, 2:])

    def update(self, tracks: TrackTable, idx: np.ndarray, boxes: np.ndarray, t: float,
               split: np.ndarray, whole_box: np.ndarray | None = None) -> SizeUpdate:
        """Update the sizes of tracks idx with their detected boxes (K, 4) at time t; split
        (K,) marks tracks whose box held several vehicles; whole_box (K,) the boxes the
        appearance model drew (provenance.py; None: none) (module docstring, steps 1-6)."""
        cfg = self.cfg
        size = tracks.size[idx]
        size_var = self.filter.px_var(tracks.s[idx], tracks.Ps[idx])
        whole_box = np.zeros(len(idx), dtype=bool) if whole_box is None else whole_box
        edges_cut = border_cut(boxes, self.width, self.height)
        cut = edges_cut.any(axis=2)
        if len(idx) == 0:
            empty = np.zeros((0, 2), dtype=bool)
            return SizeUpdate(empty, np.zeros(0, dtype=bool), size, size_var, edges_cut)
        expected = spread = np.full((len(idx), 2), np.nan)
        rates = self.rates(tracks, idx)
        # a whole box (provenance.py) away from the border is the whole vehicle
        trusted = whole_box & ~near_border(cfg, boxes, self.width, self.height)
        partial = anchored(tracks, idx, boxes, t, rates) & ~trusted               # 1
        if cfg.own_size:                                                           # 2
            expected, spread = own_size(tracks.own[idx], self.field.k(tracks.x[idx, :2]))
            expected[partial] = np.nan
            remember_size(tracks, idx, boxes, self.field.k(centre(boxes)),
                          cut.any(axis=1) | partial)
        # A vehicle receding (its box shrinking: the scene's perspective and the size
        # filter's rates) faster than its size estimate follows: the size starts again
        # from the detection.                                                        3
        sigma = detection_sigma(cfg, np.sqrt(size.prod(axis=1)))[:, None]
        receding = np.all(rates < 0, axis=1)
        smaller = ((shrunk(tracks.x[idx, :2], size, boxes, sigma) & receding & ~partial
                    | trusted)[:, None] & ~cut)
        if cfg.shrink_unexplained:
            smaller |= self._unexplained(tracks, idx, boxes, partial)[:, None] & ~cut
        # A whole side is never a border-cut one (box_size.py), so `shows_whole` has no cut.
        whole = self.filter.update(tracks, idx, boxes[:, 2:], cut, t, expected, spread,  # 4
                                   smaller)
        shows_whole = whole.all(axis=1) & ~split
        self._learn_scale(tracks, idx[shows_whole], boxes[shows_whole])              # 5
        if split.any():                                                              # 6
            k = idx[split]
            s_new, Ps_new = self.initial(boxes[split])
            s_new[:, 2:], Ps_new[:, 2:, 2:] = tracks.s[k, 2:], tracks.Ps[k][:, 2:, 2:]
            tracks.s[k], tracks.Ps[k] = s_new, Ps_new
        return SizeUpdate(whole, shows_whole, size, size_var, edges_cut)

    def _unexplained(self, tracks: TrackTable, idx: np.ndarray, boxes: np.ndarray,
                     partial: np.ndarray) -> np.ndarray:
        """(K,) detections (K, 4) of tracks idx that nothing shows to be a partial view:
        not anchored (`partial`, a static occluder's edge) and overlapping no other track's
        predicted box (a vehicle in front, or a neighbour merged). A side of such a
        detection smaller than the size gate is the vehicle's, at once (box_size.py)."""
        others = touches_other(boxes, idx, tracks.boxes(self.width, self.height))
        return ~partial & ~others

    def _learn_scale(self, tracks: TrackTable, idx: np.ndarray, boxes: np.ndarray) -> None:
        """Feed the scale field with whole-vehicle boxes of confirmed tracks whose box
        overlaps no other track's: a pair once the track has moved half a box scale."""
        conf = tracks.id[idx] > 0
        idx, boxes = idx[conf], boxes[conf]
        if len(idx) == 0:
            return
        all_boxes = tracks.boxes(self.width, self.height)
        alone = ~touches_other(all_boxes[idx], idx, all_boxes)
        idx, boxes = idx[alone], boxes[alone]
        p = centre(boxes)
        sc = scale(boxes)
        ref = tracks.ref_s[idx]
        far = np.hypot(*(p - tracks.ref_p[idx]).T) >= 0.5 * np.fmin(sc, ref)
        pair = np.isfinite(ref) & far
        self.field.add(tracks.ref_p[idx[pair]], ref[pair], p[pair], sc[pair])
        new = ~np.isfinite(ref) | pair
        tracks.ref_p[idx[new]], tracks.ref_s[idx[new]] = p[new], sc[new]


def touches_other(query: np.ndarray, owners: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(K,) whether each query box (K, 4) overlaps any of `boxes` (N, 4) other than its
    owner's (`owners` (K,), indices into boxes). Boxes that overlap have centres within the
    sum of their half diagonals: k-d tree pairs within the largest diagonal."""
    if len(query) == 0 or len(boxes) == 0:
        return np.zeros(len(query), dtype=bool)
    radius = (np.hypot(query[:, 2], query[:, 3]).max()
              + np.hypot(boxes[:, 2], boxes[:, 3]).max()) / 2
    near = cKDTree(centre(boxes)).query_ball_point(centre(query), float(radius))
    qi = np.repeat(np.arange(len(query)), [len(n) for n in near])
    pj = np.fromiter((j for n in near for j in n), dtype=int, count=len(qi))
    other = pj != owners[qi]
    qi, pj = qi[other], pj[other]
    touching = qi[intersection(query[qi], boxes[pj]) > 0]
    return np.bincount(touching, minlength=len(query)) > 0
