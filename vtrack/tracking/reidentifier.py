"""Re-identification: a vehicle lost for longer than a track coasts comes back with its id.

A vehicle hidden behind another vehicle or under a gantry for a few seconds outlives its
track (`max_coast_seconds`); when it reappears, a new track starts on it. A confirmed track
that ends without a detection for at least `max_coast_seconds` while its box is still in
the image is remembered for `reid_seconds` after its last detection: its id, the time,
centre and scale of its last detected box, its velocity then and its colour (the running
mean of its detections' colour signatures, vision/colour.py). A track that confirms later
takes a remembered id instead of a new one where it is the vehicle's continuation:
- its first detection came after the lost track's last one;
- its first box is clear of the image border (a vehicle whose box first showed at the
  border drove into the picture);
- its centre lies within `reid_gate` box scales, plus TRAVEL_SHARE of the way predicted, of
  where the lost vehicle is predicted: on at its last velocity from its last detection (the
  vehicle may have braked or gone on while unseen);
- its box scale differs from the last detected one by less than `reid_scale_ratio`;
- its colour matches: Bhattacharyya coefficient >= `reid_colour`.
Lost tracks and new ones are paired by the Hungarian method on the distance over the gate
plus the colours' dissimilarity. A track that a confirmed track already continues when it
ends (one that started on the vehicle while the old one still coasted) is not remembered:
its id on a third track would give the vehicle two.

Motion alone does not tell a vehicle from the next one in its lane: on the scene suite 8 of
11 hand-overs by the motion tests alone went to another vehicle (docs/TRACKER.md,
"Re-identification"). Without colours (a tracker fed boxes only) nothing is re-identified.

While an id is remembered the counts keep its record open (FrameTracks.held): a line it
crossed before it was hidden is not counted again, and its movement runs from its first
gate to its last.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np
from scipy.optimize import linear_sum_assignment

from vtrack.boxes import centre, from_edges, on_border, scale
from vtrack.tracking.columns import Columns, warp_scale
from vtrack.tracking.config import TrackerConfig

if TYPE_CHECKING:
    from vtrack.tracking.table import TrackTable

SIGNATURE_SIZE = 128  # bins of a colour signature (vision/colour.py: hue x saturation x value)
COLOUR_RATE = 0.2     # a detection's weight in a track's running colour
BORDER_PX = 1.0       # a first box this close to the image border showed at the border
TRAVEL_SHARE = 0.5    # the gate widens by this share of the way the prediction went unseen


def colour_similarity(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(A, B) Bhattacharyya coefficients sum(sqrt(p q)) of signatures a (A, S), b (B, S)."""
    return np.sqrt(np.maximum(a, 0.0)) @ np.sqrt(np.maximum(b, 0.0)).T


@dataclass
class ReidColumns(Columns):
    """Per track: what re-identifies its vehicle once it is lost."""

    born: np.ndarray       # (N,) time of its first detection
    v_seen: np.ndarray     # (N, 2) its velocity after its last detection's update, px/s
    colour: np.ndarray     # (N, SIGNATURE_SIZE) running mean of its colour signatures (0: none)

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "born": ((), float), "v_seen": ((2,), float), "colour": ((SIGNATURE_SIZE,), float)}

    @classmethod
    def new(cls, k: int, t: float) -> Self:
        """The rows of k tracks first detected at time t (the detection fills the rest)."""
        return cls(np.full(k, t), np.zeros((k, 2)), np.zeros((k, SIGNATURE_SIZE)))

    def warp(self, m: np.ndarray) -> None:
        """Velocities map by the camera motion's linear part."""
        self.v_seen = self.v_seen @ m[:, :2].T


@dataclass
class LostColumns(Columns):
    """Per remembered track."""

    id: np.ndarray         # (M,) its public id
    t_seen: np.ndarray     # (M,) time of its last detection
    p: np.ndarray          # (M, 2) its last detected box's centre
    v: np.ndarray          # (M, 2) its velocity after that detection, px/s
    scale: np.ndarray      # (M,) its last detected box's scale
    colour: np.ndarray     # (M, SIGNATURE_SIZE)

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "id": ((), int), "t_seen": ((), float), "p": ((2,), float), "v": ((2,), float),
        "scale": ((), float), "colour": ((SIGNATURE_SIZE,), float)}

    def warp(self, m: np.ndarray) -> None:
        """Centres map by m, velocities by its linear part, scales by sqrt|det A|."""
        self.p = self.p @ m[:, :2].T + m[:, 2]
        self.v = self.v @ m[:, :2].T
        self.scale = self.scale * warp_scale(m)


class Reidentifier:
    """Remembers the confirmed tracks lost in view and hands their ids to the tracks that
    continue them (module docstring)."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int) -> None:
        self.cfg = cfg
        self.width, self.height = width, height
        self.lost = LostColumns.empty()

    @property
    def held(self) -> np.ndarray:
        """The remembered ids: vehicles that may still come back."""
        return self.lost.id.copy()

    def observe(self, tracks: TrackTable, idx: np.ndarray, colours: np.ndarray | None
                ) -> None:
        """Tracks idx were detected this frame (after their update), with these colour
        signatures (K, SIGNATURE_SIZE) or none: keep their velocity and fold the colours
        into their running mean (a track's first signature starts it)."""
        tracks.v_seen[idx] = tracks.x[idx, 2:4]
        if colours is None or len(idx) == 0:
            return
        old = tracks.colour[idx]
        rate = np.where(old.sum(axis=1) > 0, COLOUR_RATE, 1.0)[:, None]
        tracks.colour[idx] = (1.0 - rate) * old + rate * colours

    def claim(self, tracks: TrackTable, ready: np.ndarray, t: float) -> np.ndarray:
        """For the tracks `ready` to confirm at time t, the id each continues (0: a new
        vehicle); the ids handed on are forgotten."""
        ids = np.zeros(len(ready), dtype=int)
        cfg, lost = self.cfg, self.lost
        if cfg.reid_seconds <= 0 or len(ready) == 0 or len(lost) == 0:
            return ids
        entered = on_border(from_edges(tracks.origin[ready]), self.width, self.height,
                            BORDER_PX).any(axis=(1, 2))
        clear = np.flatnonzero(~entered)
        new = ready[clear]
        ok, cost = self._continues(tracks, new, t)
        if not ok.any():
            return ids
        rows, cols = linear_sum_assignment(np.where(ok, cost, 1e6))
        pairs = ok[rows, cols]
        ids[clear[rows[pairs]]] = lost.id[cols[pairs]]
        kept = np.ones(len(lost), dtype=bool)
        kept[cols[pairs]] = False
        lost.keep(kept)
        return ids

    def _continues(self, tracks: TrackTable, idx: np.ndarray, t: float,
                   lost: LostColumns | None = None, sized: bool = True
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Whether each of tracks idx may continue each lost track at time t (K, M; default:
        the remembered ones) by the tests of the module docstring (`sized` False: all but
        the scale's), and the cost of the pairing: the distance over the gate plus the
        colours' dissimilarity."""
        cfg = self.cfg
        lost = self.lost if lost is None else lost
        gone = t - lost.t_seen
        radius = cfg.reid_gate * lost.scale + TRAVEL_SHARE * np.linalg.norm(lost.v, axis=1) * gone
        predicted = lost.p + lost.v * gone[:, None]
        dist = np.linalg.norm(tracks.x[idx, None, :2] - predicted[None], axis=2) / radius
        ratio = np.abs(np.log(tracks.scale[idx, None] / lost.scale[None]))
        colour = colour_similarity(tracks.colour[idx], lost.colour)
        ok = ((dist <= 1.0) & ((ratio < np.log(cfg.reid_scale_ratio)) | (not sized))
              & (colour >= cfg.reid_colour) & (tracks.born[idx, None] > lost.t_seen[None] + 1e-9))
        return ok, dist + (1.0 - colour)

    def remember(self, tracks: TrackTable, ended: np.ndarray, inside: np.ndarray, t: float
                 ) -> None:
        """Keep the tracks among `ended` (N,) that were confirmed, are in view (`inside`),
        ended lost (undetected for at least max_coast_seconds) and have a colour; forget
        the remembered ones whose last detection is more than reid_seconds old. A track
        that a confirmed track already continues as it ends (one that started on the
        vehicle while it still coasted; whatever its size: the lost track's last box may
        have been a part) is not kept: its id on a third track would give the vehicle
        two."""
        cfg, lost = self.cfg, self.lost
        if cfg.reid_seconds <= 0:
            return
        lost.keep(t - lost.t_seen <= cfg.reid_seconds + 1e-9)
        seen = tracks.hist_t[:, 0]
        k = np.flatnonzero(ended & inside & (tracks.id > 0) & (tracks.colour.sum(axis=1) > 0)
                           & (t - seen >= cfg.max_coast_seconds - 1e-9))
        if len(k) == 0:
            return
        box = from_edges(tracks.last_box[k])
        ended_now = LostColumns(tracks.id[k].copy(), seen[k].copy(), centre(box),
                                tracks.v_seen[k].copy(), scale(box), tracks.colour[k].copy())
        going = np.flatnonzero((tracks.id > 0) & ~ended)
        continued = self._continues(tracks, going, t, ended_now, sized=False)[0].any(axis=0)
        ended_now.keep(~continued)
        lost.append(ended_now)
