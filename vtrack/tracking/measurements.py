"""Per-vehicle measurements: a detected box as a measurement of a track's centre (nested
boxes), and seed 001's position plus finite-difference velocity and acceleration
(eqs. 24-26) processed consistently.

For detections p_k, p_{k-1}, p_{k-2} at spacings h1 = t_k - t_{k-1}, h2 = t_{k-1} - t_{k-2}:

    v = (p_k - p_{k-1}) / h1
    a = 2 [(p_k - p_{k-1}) / h1 - (p_{k-1} - p_{k-2}) / h2] / (h1 + h2)

(equal spacing gives the seed's (p_k - 2 p_{k-1} + p_{k-2}) / dt^2). Per axis z = (p, v, a)
= D (p_k, p_{k-1}, p_{k-2}) = D0 p_k + D1 p_{k-1} + D2 p_{k-2}, Dj the columns of D.

The seed treats z as x + white noise with R = D Sigma D' (SEEDS 3.1; mode
'finite-difference-white'). It is not white: consecutive z share detections, so their errors
are correlated in time and that filter is overconfident (ANEES ~10 for 6 states; tests).
Written as it is formed, z given the detections already assimilated is

    z = D0 p_k + c,   c = D1 p_{k-1} + D2 p_{k-2}  (known numbers),   p_k = H x + e_k,

an affine function of the new detection alone: its innovation is D0 (p_k - H x-), of rank
one per axis, and the update it implies -- D0's pseudo-inverse maps it back -- is the update
with p_k = D0+ (z - c), H the position rows and R the detection's variance (mode
'finite-difference'). So the consistent filter of the seed's measurement extracts the new
detection from z and gains nothing from the differences beyond it: the same estimate as the
textbook position-only filter, and consistent (ANEES in the chi-square band; tests).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vtrack.boxes import edges, on_border
from vtrack.tracking.columns import Columns, warp_scale
from vtrack.tracking.config import TrackerConfig

if TYPE_CHECKING:
    from vtrack.tracking.sizes import SizeUpdate
    from vtrack.tracking.table import TrackTable

MODES = ("finite-difference", "finite-difference-white", "position")


def detection_sigma(cfg: TrackerConfig, scale: np.ndarray) -> np.ndarray:
    """Std (px) of a detected centre for boxes of scale `scale` (px): scale-free, >= 0.5."""
    return np.maximum(cfg.detection_sigma * scale, 0.5)


@dataclass
class HistoryColumns(Columns):
    """Per track: the last three detected centres the measurement differences."""

    hist_p: np.ndarray     # (N, 3, 2) last three detected centres, newest first
    hist_t: np.ndarray     # (N, 3) their times
    hist_s: np.ndarray     # (N, 3, 2) their stds
    count: np.ndarray      # (N,) detections so far, capped at 3 (for the differences)

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "hist_p": ((3, 2), float), "hist_t": ((3,), float), "hist_s": ((3, 2), float),
        "count": ((), int)}

    @classmethod
    def new(cls, k: int, t: float) -> HistoryColumns:
        """The rows of k tracks born at time t: no detection yet."""
        return cls(np.zeros((k, 3, 2)), np.full((k, 3), t), np.zeros((k, 3, 2)),
                   np.zeros(k, dtype=int))

    def warp(self, m: np.ndarray) -> None:
        """Centres map by m, their stds scale by sqrt|det A|."""
        self.hist_s = self.hist_s * warp_scale(m)
        self.hist_p = self.hist_p @ m[:, :2].T + m[:, 2]


class CentreMeasurement:
    """A track's detected box as a measurement of its centre filter: the centre the box
    gives (`box_centre`, from what the size role decided it showed), pushed into the
    track's last three detections, and seed 001's measurement of those
    (`measurement_model`, TrackerConfig.measurement)."""

    def __init__(self, cfg: TrackerConfig) -> None:
        self.cfg = cfg

    def measure(self, tracks: TrackTable, idx: np.ndarray, boxes: np.ndarray, t: float,
                sizes: SizeUpdate) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(z, H, R, mask) of tracks idx from their detected boxes (K, 4) at time t; records
        the detection in each track's history and last box."""
        pos_var = tracks.P[idx][:, [0, 1], [0, 1]]
        sigma = detection_sigma(self.cfg, np.sqrt(sizes.size.prod(axis=1)))[:, None]
        centers, var = box_centre(tracks.x[idx, :2], pos_var, sizes.size, sizes.size_var,
                                  boxes, sizes.whole, sigma, sizes.cut)
        for hist, newest in ((tracks.hist_s, np.sqrt(var)), (tracks.hist_p, centers),
                             (tracks.hist_t, t)):
            hist[idx, 1:] = hist[idx, :-1]  # fancy indexing copies before the write
            hist[idx, 0] = newest
        tracks.count[idx] = np.minimum(tracks.count[idx] + 1, 3)
        tracks.last_box[idx] = edges(boxes)
        return measurement_model(tracks.hist_p[idx], tracks.hist_t[idx], tracks.count[idx],
                                 tracks.hist_s[idx], self.cfg.measurement)


def difference_operator(h1: np.ndarray, h2: np.ndarray) -> np.ndarray:
    """D (..., 3, 3) mapping (p_k, p_{k-1}, p_{k-2}) of one axis to (p, v, a)."""
    h1 = np.asarray(h1, dtype=float)
    h2 = np.asarray(h2, dtype=float)
    D = np.zeros(h1.shape + (3, 3))
    D[..., 0, 0] = 1.0
    D[..., 1, 0] = 1.0 / h1
    D[..., 1, 1] = -1.0 / h1
    D[..., 2, 0] = 2.0 / (h1 * (h1 + h2))
    D[..., 2, 1] = -2.0 / (h1 * h2)
    D[..., 2, 2] = 2.0 / (h2 * (h1 + h2))
    return D


def backward_positions(h1: np.ndarray, h2: np.ndarray) -> np.ndarray:
    """Phi_back (..., 3, 3): (p, v, a) of one axis at t_k -> positions at t_k, t_{k-1},
    t_{k-2} under constant acceleration (seed 001 eq. 22 run backwards)."""
    h1 = np.asarray(h1, dtype=float)
    s = h1 + np.asarray(h2, dtype=float)
    P = np.zeros(h1.shape + (3, 3))
    P[..., :, 0] = 1.0
    P[..., 1, 1], P[..., 1, 2] = -h1, h1**2 / 2
    P[..., 2, 1], P[..., 2, 2] = -s, s**2 / 2
    return P


def finite_difference_measurement(points: np.ndarray, times: np.ndarray, count: np.ndarray,
                                  sigma: float | np.ndarray, position_only: bool = False
                                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The seed's measurement of N tracks in the state layout [x, y, vx, vy, ax, ay].

    points (N, 3, 2): the last three detected centres, newest first; times (N, 3) their times;
    count (N,): how many of them exist (1, 2 or 3); sigma: the std of each detected centre, a
    number or (N, 3, 2) per detection and axis. Returns z (N, 6), the seed's white-noise
    R = D diag(sigma^2) D' (N, 6, 6) and the mask (N, 6) of rows present: a track with one
    detection measures its position only, with two also its velocity (eqs. 24-25);
    position_only keeps only the position rows.
    """
    n = len(points)
    D, z = _differences(points, times, count)
    var = np.broadcast_to(np.asarray(sigma, dtype=float) ** 2, (n, 3, 2))
    R = np.zeros((n, 6, 6))
    for axis in (0, 1):
        R[:, axis::2, axis::2] = (D * var[:, None, :, axis]) @ np.swapaxes(D, -1, -2)
    return z, R, _rows(count, position_only)


def measurement_model(points: np.ndarray, times: np.ndarray, count: np.ndarray,
                      sigmas: np.ndarray, mode: str
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(z, H, R, mask) of N tracks over the state [x, y, vx, vy, ax, ay] from their last
    three detections `points` (N, 3, 2) at `times` (N, 3), `count` (N,) of them, with stds
    `sigmas` (N, 3, 2): 'finite-difference' processes the seed's z consistently (the new
    detection D0+ (z - c) on the position rows, see the module docstring),
    'finite-difference-white' the seed's white model (H = I6, R = D Sigma D'), 'position'
    the position rows."""
    n = len(points)
    H = np.broadcast_to(np.eye(6), (n, 6, 6))
    if mode == "finite-difference-white":
        z, R, mask = finite_difference_measurement(points, times, count, sigmas)
        return z, H, R, mask
    D, z = _differences(points, times, count)
    if mode == "finite-difference":
        z[:, :2] = new_detection(z, points, times, count, _rows(count, position_only=False),
                                 D)
    R = np.zeros((n, 6, 6))
    R[:, [0, 1], [0, 1]] = sigmas[:, 0] ** 2
    return z, H, R, _rows(count, position_only=True)


def new_detection(z: np.ndarray, points: np.ndarray, times: np.ndarray, count: np.ndarray,
                  mask: np.ndarray, D: np.ndarray | None = None) -> np.ndarray:
    """The new detection p_k = D0+ (z - c) recovered from the seed's measurement z (N, 6)
    over its present rows `mask`, with c = D1 p_{k-1} + D2 p_{k-2} from the detections
    already assimilated (module docstring); (N, 2). `D`: the difference operators of
    `times` (N, 3, 3), when at hand."""
    n = len(z)
    D = _operator(times, count) if D is None else D
    c = np.einsum("nij,njd->nid", D[:, :, 1:], points[:, 1:]).reshape(n, 6)
    d0 = np.repeat(D[:, :, 0], 2, axis=1) * mask           # rows (p, v, a) x (x, y)
    num = (d0 * (z - c)).reshape(n, 3, 2).sum(axis=1)
    return num / (d0**2).reshape(n, 3, 2).sum(axis=1)


def _spacings(times: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # Unused spacings get a harmless placeholder; their rows are masked out.
    h1 = np.where(count >= 2, times[:, 0] - times[:, 1], 1.0)
    h2 = np.where(count >= 3, times[:, 1] - times[:, 2], 1.0)
    return h1, h2


def _operator(times: np.ndarray, count: np.ndarray) -> np.ndarray:
    return difference_operator(*_spacings(times, count))


def _differences(points: np.ndarray, times: np.ndarray, count: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The difference operators D (N, 3, 3) of `times` and the seed's z (N, 6) of `points`
    (finite_difference_measurement)."""
    D = _operator(times, count)
    z = np.einsum("nij,njd->nid", D, points).reshape(len(points), 6)   # [x, y, vx, ...]
    return D, z


def _rows(count: np.ndarray, position_only: bool) -> np.ndarray:
    rows = np.repeat(np.arange(3), 2)[None, :]                # derivative order of each row
    order = np.minimum(count, 1 if position_only else 3)[:, None]
    return rows < order


def box_centre(pred: np.ndarray, pos_var: np.ndarray, size: np.ndarray,
               size_var: np.ndarray, boxes: np.ndarray, whole: np.ndarray,
               sigma: np.ndarray, cut: np.ndarray, k: float = 3.0
               ) -> tuple[np.ndarray, np.ndarray]:
    """A detected box as a measurement (z, var) of a track's centre (K, 2 each), per axis:

    - a side that shows the whole vehicle (`whole`, box_size.py): the box's centre, variance
      sigma^2;
    - else, one edge where the track expects it (within k standard deviations: the centre's
      variance pos_var, the size's size_var / 4 px^2 and sigma^2) while the other lies
      inside the track's box: that side is hidden (an occluder, the image border), and the
      centre is the seen edge -/+ s/2 (variance sigma^2 + size_var / 4); so is a box
      smaller than the track's cut by the image border on one side (`cut`, (K, 2, 2) as
      border_cut): its inner edge is the vehicle's, wherever the track expected it (a
      vehicle leaving the picture is followed out of it);
    - else the boxes are only nested (nested_centre).
    """
    lo_box, hi_box = boxes[:, :2], boxes[:, :2] + boxes[:, 2:]
    lo_p, hi_p = pred - size / 2, pred + size / 2
    tol = k * np.sqrt(pos_var + size_var / 4 + sigma**2)
    smaller = boxes[:, 2:] < size
    seen_lo = ((np.abs(lo_box - lo_p) <= tol) & (hi_box < hi_p - tol)
               | smaller & cut[:, :, 1] & ~cut[:, :, 0])
    seen_hi = ((np.abs(hi_box - hi_p) <= tol) & (lo_box > lo_p + tol)
               | smaller & cut[:, :, 0] & ~cut[:, :, 1])
    z, var = nested_centre(pred, size, boxes, sigma)
    one = sigma**2 + size_var / 4
    z = np.where(seen_lo, lo_box + size / 2, np.where(seen_hi, hi_box - size / 2, z))
    var = np.where(seen_lo | seen_hi, one, var)
    z = np.where(whole, (lo_box + hi_box) / 2, z)
    var = np.where(whole, sigma**2, var)
    return z, var


def shrunk(pred: np.ndarray, size: np.ndarray, boxes: np.ndarray, sigma: np.ndarray
           ) -> np.ndarray:
    """(K,) whether a detected box lies inside the track's predicted box (centre pred, size
    size) at all four ends, each further in than the detection's std sigma (K, 1), on each
    axis the smaller inset at least a third of the larger and the box over half the
    predicted size: the vehicle is smaller than predicted (one receding faster than its
    estimated size shrinks). A view with an end hidden keeps the other end where
    predicted, so its centre is off by half the missing length; this one is about centred
    (off by under a quarter of it), on both axes, as perspective shrinks a vehicle; a far
    smaller box inside is a piece (of a merge, of a vehicle), not the vehicle shrunk."""
    lo = boxes[:, :2] - (pred - size / 2)
    hi = pred + size / 2 - (boxes[:, :2] + boxes[:, 2:])
    inset = np.minimum(lo, hi)
    return np.all((inset > sigma) & (3 * inset > np.maximum(lo, hi)) & (lo + hi < size / 2),
                  axis=1)


def nested_centre(pred: np.ndarray, size: np.ndarray, boxes: np.ndarray, sigma: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """A detected box as a measurement (z, var) of a track's centre (K, 2 each).

    A detection smaller than the vehicle (partly hidden by an occluder or the image border)
    or larger (merged with a shadow, a ghost or another vehicle) only says that the track's
    box (predicted centre `pred`, size `size`) and the detected box are nested. Per axis that
    puts the vehicle's centre in the interval between d0 + s/2 and d1 - s/2 (detection
    [d0, d1], track box size s), of length |w_det - s|; for a detection of the vehicle's size
    it is the detection's centre. z is the prediction clipped to that interval and its
    variance is the detector's sigma^2 (K, 2) plus that of a uniform spread over the
    interval, L^2 / 12.
    """
    half = size / 2
    a = boxes[:, :2] + half
    b = boxes[:, :2] + boxes[:, 2:] - half
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    z = np.clip(pred, lo, hi)
    return z, sigma**2 + (hi - lo) ** 2 / 12.0


def border_cut(boxes: np.ndarray, width: int, height: int, tol: np.ndarray | None = None
               ) -> np.ndarray:
    """(K, 2, 2): which edges (axis x low/high) of boxes (x, y, w, h) lie on the image
    border (within half a pixel, or within `tol` (K,) px of it), where the vehicle may go on
    beyond the picture."""
    if tol is None:
        return on_border(boxes, width, height)
    lo, hi = boxes[:, :2], boxes[:, :2] + boxes[:, 2:]
    t = np.maximum(tol, 0.5)[:, None]
    return np.stack([lo <= t, hi >= np.array([width, height]) - t], axis=2)
