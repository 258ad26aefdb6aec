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
  starts again from the detection;
- a vehicle coming out from behind an occluder or into the picture grows by at most the
  distance it travelled (its `reach`, and at most double): such growth sets the size to
  the detection at once,
  without teaching the rate (emerging is not perspective growth); a larger jump is a merge;
- a side cut by the image border is a lower bound: smaller than predicted, it says nothing.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri
from vtrack.estimation.kalman import kf_predict, kf_update
from vtrack.estimation.models import WienerVelocity
from vtrack.tracking.table import TrackTable


class BoxSizeFilter:
    """Predict and update the box sizes of a stack of tracks (see the module docstring)."""

    def __init__(self, size_psd: float, size_sigma: float, rate_seconds: float,
                 gate_probability: float, reset_seconds: tuple[float, float]) -> None:
        self.model = WienerVelocity(size_psd)
        self.sigma = size_sigma
        self.tau = rate_seconds
        self.gate = float(ndtri((1 + gate_probability) / 2)) ** 2   # chi-square, 1 dof
        self.reset_seconds = reset_seconds

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
        F = self.model.transition(dt)
        F[[2, 3], [2, 3]] = np.exp(-dt / self.tau)
        return kf_predict(s, Ps, F, self.model.Q(dt))

    def px_var(self, s: np.ndarray, Ps: np.ndarray) -> np.ndarray:
        """(K, 2) variance of the box sides in px^2 (first order: (w sigma_ln w)^2)."""
        return np.exp(2 * s[:, :2]) * Ps[:, [0, 1], [0, 1]]

    def update(self, tracks: TrackTable, idx: np.ndarray, sizes: np.ndarray,
               cut: np.ndarray, t: float) -> np.ndarray:
        """Update the sizes of tracks `idx` with detected sizes (K, 2) at time t; cut (K, 2)
        marks sides on the image border. Returns whole (K, 2): the sides that showed the
        whole vehicle and updated the size (the module docstring)."""
        s, Ps = tracks.s[idx], tracks.Ps[idx]
        z = np.log(np.maximum(sizes, 1.0))
        var = self._var(sizes)
        nu = z - s[:, :2]
        whole = (nu**2 <= self.gate * (Ps[:, [0, 1], [0, 1]] + var)) & ~cut
        if whole.any():
            H = np.broadcast_to(np.eye(2, 4), (len(s), 2, 4))
            s, Ps, _ = kf_update(s, Ps, nu, H, var[:, :, None] * np.eye(2), mask=whole)
        # Runs of mismatch in one direction (cut sides: only growth counts).
        sign = np.sign(nu)
        rejected = ~whole & ~(cut & (nu <= 0))
        same = rejected & (sign == tracks.mismatch_sign[idx])
        start = np.where(same, tracks.mismatch_t[idx], t)
        wait = np.where(nu > 0, self.reset_seconds[0], self.reset_seconds[1])
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
        return whole
