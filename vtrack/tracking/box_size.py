"""The box size filter: each track's width and height with their rates, estimated.

State per track: [ln w, ln h, d ln w/dt, d ln h/dt]: the log sizes with their rates. The
scene's perspective gives most of a vehicle's growth from its motion (scale_field.py); the
state's rates are the rest, mean-reverting (Ornstein-Uhlenbeck with time constant `size_rate_seconds`: without
measurements a rate decays to zero instead of inflating the box for ever) and driven by
white noise of density `size_psd` (Q of the core's Wiener-velocity model). SORT carries the
box's area and aspect with their rates; logs make the perspective growth of a vehicle
driving toward the camera (size ~ 1 / distance) close to a constant rate, and a relative
error the same for a far and a near vehicle.

A detected box measures ln w and ln h with std `size_sigma` (relative) plus a pixel of
outline noise, where it shows the whole vehicle:
- a side whose innovation is outside the chi-square gate (1 dof) is a partial view (an
  occluder hides part of the vehicle) or a merge (a shadow, a neighbour): it leaves the size
  to its prediction, and the centre then only knows that the boxes are nested
  (measurements.box_centre). A mismatch in the same direction for a while means the
  estimate is what is wrong (a track started on a part of a vehicle, or on two): the size
  starts again from the detection, without teaching the rate (emerging is not perspective
  growth). "A while" is `size_grow_seconds` for a larger detection (0 by default: a
  vehicle coming into the picture or out from behind an occluder grows at once, and
  capping that growth by the distance travelled lost 0.13 of the suite's mean MOTA) and
  `size_shrink_seconds` for a smaller one (an occluder hides part of a vehicle for a
  while);
- a side cut by the image border is a lower bound: smaller than predicted, it says nothing;
- a vehicle receding faster than its size estimate shrinks (near a pole camera) is detected
  inside the predicted box, about centred, at both ends of both axes; a partial view keeps
  one end where predicted. Such a detection shows the whole vehicle: the size starts again
  from it at once (measurements.shrunk);
- the vehicle's own size: the median of its last OWN detections, each divided by the scene's
  scale field where it was seen (`own_size`), carried to where the vehicle is now. A
  detected side of that size, within the scatter of the vehicle's own detections, is the
  whole vehicle's even where the estimate disagrees: the size starts again from it at once
  (a track born on a merged blob, or grown by a merge, gets its vehicle's box back in a
  few frames instead of `size_shrink_seconds`). A detection with an edge that stays put
  while the vehicle moves is a partial view behind a static occluder (`anchored`): it
  neither enters the memory nor resets the size.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.special import ndtri

from vtrack.boxes import edges as box_edges
from vtrack.estimation.kalman import kf_predict, kf_update
from vtrack.estimation.models import WienerVelocity

if TYPE_CHECKING:
    from vtrack.tracking.config import TrackerConfig
    from vtrack.tracking.table import TrackTable

OWN = 9  # detections whose median gives a vehicle's own size (`own_size`)

OWN_SPREAD = 0.5    # ln spread of a vehicle's detected sides beyond which its size is unknown
ANCHOR_SHARE = 0.3  # an edge moving less than this share of its expected motion stays put
ANCHOR_SIGMAS = 3.0  # a velocity this many standard deviations from zero is motion


class BoxSizeFilter:
    """Predict and update the box sizes of a stack of tracks (see the module docstring)."""

    def __init__(self, size_psd: float, size_sigma: float, rate_seconds: float,
                 gate_probability: float, reset_seconds: tuple[float, float]) -> None:
        self.model = WienerVelocity(size_psd)
        self.sigma = size_sigma
        self.tau = rate_seconds
        self.gate = float(ndtri((1 + gate_probability) / 2)) ** 2   # chi-square, 1 dof
        self.reset_seconds = reset_seconds

    @classmethod
    def from_config(cls, cfg: TrackerConfig) -> BoxSizeFilter:
        """The filter with the [tracker] size parameters."""
        return cls(cfg.size_psd, cfg.size_sigma, cfg.size_rate_seconds,
                   cfg.size_gate_probability, (cfg.size_grow_seconds, cfg.size_shrink_seconds))

    def _var(self, sizes: np.ndarray) -> np.ndarray:
        """Variance of a detected ln size: the relative std plus one pixel of outline."""
        return self.sigma**2 + (1.0 / np.maximum(sizes, 1.0)) ** 2

    def initial(self, sizes: np.ndarray, rate_sigma: float) -> tuple[np.ndarray, np.ndarray]:
        """(s, Ps) of new tracks from their detected sizes (K, 2), rates unknown (std
        rate_sigma, 1/s)."""
        k = len(sizes)
        s = np.zeros((k, 4))
        s[:, :2] = np.log(np.maximum(sizes, 1.0))
        Ps = np.zeros((k, 4, 4))
        Ps[:, [0, 1], [0, 1]] = self._var(sizes)
        Ps[:, [2, 3], [2, 3]] = rate_sigma**2
        return s, Ps

    def predict(self, s: np.ndarray, Ps: np.ndarray, dt: float, log_rate: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Propagate over dt (s); log_rate (K,) is the growth d ln s/dt the scene's
        perspective gives each vehicle's motion (scale_field.py), the state's rates are
        what is left."""
        if len(s) == 0 or dt <= 0:
            return s, Ps
        s = s.copy()
        s[:, :2] += (log_rate * dt)[:, None]
        F = self.model.transition(dt).copy()
        F[[2, 3], [2, 3]] = np.exp(-dt / self.tau)
        return kf_predict(s, Ps, F, self.model.Q(dt))

    def in_gate(self, s: np.ndarray, Ps: np.ndarray, sizes: np.ndarray) -> np.ndarray:
        """(K, 2) whether detected sides `sizes` (K, 2) lie within the size gate of the
        states (s, Ps): nu^2 <= gate (P_ln + var), nu = ln z - ln s (1 dof)."""
        nu = np.log(np.maximum(sizes, 1.0)) - s[:, :2]
        return nu**2 <= self.gate * (Ps[:, [0, 1], [0, 1]] + self._var(sizes))

    def d2(self, s: np.ndarray, Ps: np.ndarray, sizes: np.ndarray, cut: np.ndarray
           ) -> np.ndarray:
        """(K,) squared Mahalanobis distance of detected sides `sizes` (K, 2) from the
        states (s, Ps), summed over the sides; a side cut by the border (`cut` (K, 2)) that
        is smaller than predicted is a lower bound and adds nothing."""
        nu = np.log(np.maximum(sizes, 1.0)) - s[:, :2]
        d2 = nu**2 / (Ps[:, [0, 1], [0, 1]] + self._var(sizes))
        return np.where(cut & (nu < 0), 0.0, d2).sum(axis=1)

    def px_var(self, s: np.ndarray, Ps: np.ndarray) -> np.ndarray:
        """(K, 2) variance of the box sides in px^2 (first order: (w sigma_ln w)^2)."""
        return np.exp(2 * s[:, :2]) * Ps[:, [0, 1], [0, 1]]

    def update(self, tracks: TrackTable, idx: np.ndarray, sizes: np.ndarray,
               cut: np.ndarray, t: float, expected: np.ndarray, spread: np.ndarray,
               shrunk: np.ndarray, trusted: np.ndarray | None = None) -> np.ndarray:
        """Update the sizes of tracks `idx` with detected sizes (K, 2) at time t; cut (K, 2)
        marks sides on the image border; expected (K, 2) is the box size each track's
        vehicle has at its place (nan: not known) and spread (K, 2) the relative std of its
        detected sides (`own_size`); shrunk (K, 2) marks the sides of a receding vehicle
        whose detection lies centred inside the predicted box (measurements.shrunk): the
        size starts again from it at once. Returns whole (K, 2): the sides that showed the
        whole vehicle (the module docstring)."""
        s, Ps = tracks.s[idx], tracks.Ps[idx]
        z = np.log(np.maximum(sizes, 1.0))
        var = self._var(sizes)
        nu = z - s[:, :2]
        whole = self.in_gate(s, Ps, sizes) & ~cut
        if trusted is not None:   # sides of whole boxes: measurements, wherever they lie
            whole |= trusted
        # The vehicle's own size at this place (nan: not known): a detected side of that
        # size, within the scatter of the vehicle's own detections and a pixel of outline,
        # is the whole vehicle's even where the estimate disagrees (the estimate is what is
        # wrong).
        fits = ((z - np.log(expected)) ** 2
                <= self.gate * (spread**2 + (1.0 / np.maximum(sizes, 1.0)) ** 2)) & ~cut
        fits |= shrunk
        if whole.any():
            H = np.broadcast_to(np.eye(2, 4), (len(s), 2, 4))
            s, Ps, _ = kf_update(s, Ps, nu, H, var[:, :, None] * np.eye(2), mask=whole)
        # Runs of mismatch in one direction (cut sides: only growth counts).
        sign = np.sign(nu)
        rejected = ~whole & ~(cut & (nu <= 0))
        same = rejected & (sign == tracks.mismatch_sign[idx])
        start = np.where(same, tracks.mismatch_t[idx], t)
        wait = np.where(fits, 0.0,
                        np.where(nu > 0, self.reset_seconds[0], self.reset_seconds[1]))
        reset = rejected & (t - start >= wait - 1e-9)
        k, a = np.nonzero(reset)
        if len(k):
            s[k, a] = z[k, a]
            Ps[k, a, :] = 0.0
            Ps[k, :, a] = 0.0
            Ps[k, a, a] = var[k, a]
            Ps[k, a + 2, a + 2] = tracks.Ps[idx[k], a + 2, a + 2]
        tracks.s[idx], tracks.Ps[idx] = s, Ps
        tracks.mismatch_t[idx] = np.where(rejected & ~reset, start, np.nan)
        tracks.mismatch_sign[idx] = np.where(rejected & ~reset, sign, 0.0)
        return whole | (reset & fits)


def own_size(own: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box size (K, 2) vehicles have where the scale field is k (K,), and the relative
    std (K, 2) of their detected sides, from `own` (K, OWN, 2), the ln widths and heights of
    their last detections each divided by the field there (s = m k(p), scale_field.py):
    exp(median) k and 1.4826 MAD. nan until OWN detections, and where the middle ones
    disagree by more than OWN_SPREAD (a vehicle seen now whole, now in pieces)."""
    ranked = np.sort(own, axis=1)                  # nan (not yet seen) sorts last
    middle = own.shape[1] // 2
    m = np.where(np.isnan(ranked[:, -1]), np.nan, ranked[:, middle])
    # the median of OWN (odd) values is the middle one; where m is nan all are nan
    sigma = 1.4826 * np.sort(np.abs(own - m[:, None]), axis=1)[:, middle]
    m[ranked[:, -2] - ranked[:, 1] > OWN_SPREAD] = np.nan
    return np.exp(m) * k[:, None], sigma


def remember_size(tracks: TrackTable, idx: np.ndarray, boxes: np.ndarray, k: np.ndarray,
                  skip: np.ndarray) -> None:
    """Push the ln width and height of detections (K, 4), divided by the scale field k (K,)
    at their centres, into the own-size memory of tracks idx, except where `skip`."""
    idx, boxes, k = idx[~skip], boxes[~skip], k[~skip]
    own = tracks.own
    own[idx, 1:] = own[idx, :-1]
    own[idx, 0] = np.log(np.maximum(boxes[:, 2:], 1.0)) - np.log(k)[:, None]


def anchored(tracks: TrackTable, idx: np.ndarray, boxes: np.ndarray, t: float,
             size_rates: np.ndarray) -> np.ndarray:
    """(K,) True where a detection (K, 4) of tracks idx at time t has an edge that stayed
    put since the track's last detection where the whole vehicle's edge would have moved:
    the edge of a static occluder, so the detection shows part of the vehicle.

    A whole vehicle's near and far edges move by v dt -/+ (dw/dt) dt / 2 on each axis
    (size_rates (K, 2), px/s: perspective growth and the size filter's rates), so the far
    edge of a vehicle approaching a pole camera can stand still while it grows. An edge
    counts as put only on an axis the vehicle is known to move along (its velocity more
    than ANCHOR_SIGMAS standard deviations from zero: a truck driving across a side view
    has a vertical velocity estimate of tens of px/s, all noise) and against more than a
    pixel of expected motion."""
    dt = (t - tracks.hist_t[idx, 0])[:, None]
    v = tracks.x[idx, 2:4]
    moving = np.abs(v) > ANCHOR_SIGMAS * np.sqrt(tracks.P[idx][:, [2, 3], [2, 3]])
    shift, grow = v * dt, size_rates * dt / 2
    expected = np.where(np.hstack([moving, moving]),
                        np.abs(np.hstack([shift - grow, shift + grow])), 0.0)
    moved = np.abs(box_edges(boxes) - tracks.last_box[idx])
    return ((expected > 1.0) & (moved < ANCHOR_SHARE * expected)).any(axis=1)
