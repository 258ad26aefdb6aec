"""The filter bank: one constant-acceleration Kalman filter per track, stepped together.

`kf` keeps every track's (x, P) in the track table and steps them as arrays through the
shared core (vtrack.estimation.kalman: the Joseph-form step the seed experiments use). The
adaptive kinds of the core (ankf1, ankf2, fuzzy-r, fuzzy-q, siim-ekf) run one core filter
object per track on the position rows and adapt their own noise from the innovations.
"""

from __future__ import annotations

import numpy as np

from vtrack.estimation.filters import GaussianFilter, make_filter
from vtrack.estimation.kalman import kf_predict, kf_update
from vtrack.estimation.models import ConstantAcceleration, position_measurement
from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.table import TrackTable


class FilterBank:
    """Predict and update the filters of the tracks in a TrackTable."""

    def __init__(self, cfg: TrackerConfig) -> None:
        self.model = ConstantAcceleration(cfg.jerk_psd)
        self.kind = cfg.filter
        # Adaptive kinds: one core filter object per track (by uid) on the position rows.
        self._objects: dict[int, GaussianFilter] = {}
        self._position = position_measurement(6, cfg.detection_sigma)

    def start(self, uids: np.ndarray, x0: np.ndarray, P0: np.ndarray) -> None:
        """Register new tracks with prior (x0, P0) (per-track objects for adaptive kinds)."""
        if self.kind == "kf":
            return
        for u, xi in zip(uids, x0, strict=True):
            self._objects[int(u)] = make_filter(self.kind, self.model, self._position, xi, P0)

    def forget(self, uids: np.ndarray) -> None:
        """Drop the filters of deleted tracks."""
        for u in uids:
            self._objects.pop(int(u), None)

    def predict(self, tracks: TrackTable, dt: float) -> None:
        """Propagate every track over dt (s) with the white-jerk model (seed 001 eq. 21)."""
        if len(tracks) == 0 or dt <= 0:
            return
        if self.kind == "kf":
            F = self.model.transition(dt)
            tracks.x, tracks.P = kf_predict(tracks.x, tracks.P, F, self.model.Q(dt))
            return
        for i, uid in enumerate(tracks.uid):
            f = self._objects[int(uid)]
            f.predict(dt)
            tracks.x[i], tracks.P[i] = f.x, f.P

    def update(self, tracks: TrackTable, idx: np.ndarray, z: np.ndarray, R: np.ndarray,
               mask: np.ndarray) -> np.ndarray:
        """Update tracks `idx` with measurements z (K, 6) of [x, y, vx, vy, ax, ay], their
        covariances R (K, 6, 6) and the rows present (mask); H = I6 (seed 001 eqs. 24-26).
        Adaptive kinds take the position rows only. Returns |position innovation| (K,), px."""
        nu = z - tracks.x[idx]
        if len(idx) and self.kind == "kf":
            H = np.tile(np.eye(6), (len(idx), 1, 1))
            tracks.x[idx], tracks.P[idx], _ = kf_update(tracks.x[idx], tracks.P[idx], nu, H,
                                                        R, mask=mask)
        elif len(idx):
            for i, zi in zip(idx, z[:, :2], strict=True):
                f = self._objects[int(tracks.uid[i])]
                f.update(zi)
                tracks.x[i], tracks.P[i] = f.x, f.P
        return np.hypot(nu[:, 0], nu[:, 1])
