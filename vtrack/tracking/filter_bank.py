"""The filter bank: one constant-acceleration Kalman filter per track, stepped together.

`kf` keeps every track's state [x, y, vx, vy, ax, ay] of the box centre (seed 001 eq. 21)
in the track table and steps all of them as arrays through the shared core
(vtrack.estimation.kalman: the Joseph-form step the seed experiments use).

The process noise is scale-free: the white-jerk density is `jerk` box scales^2 / s^5, so
q_j = jerk * L^2 for a track whose box scale is L px (a far vehicle small in the image
manoeuvres in fewer pixels than a near one).

The adaptive kinds (vtrack.adaptive: ankf1, ankf2, fuzzy-r, fuzzy-q, siim-ekf) keep one
filter object per track for what they adapt (their innovation windows, noise scales); the
state stays in the track table: each step hands the object the track's (x, P) and takes
the result back, so there is one copy of every track's state.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from vtrack.estimation.filters import GaussianFilter
from vtrack.filter_kinds import make_filter
from vtrack.estimation.kalman import kf_predict, kf_update
from vtrack.estimation.models import (ConstantAcceleration, position_measurement,
                                      singer_transition)
from vtrack.tracking.columns import Columns
from vtrack.tracking.config import TrackerConfig

if TYPE_CHECKING:
    from vtrack.tracking.table import TrackTable


@dataclass
class CentreColumns(Columns):
    """The centre filters' state per track."""

    x: np.ndarray          # (N, 6) filtered [x, y, vx, vy, ax, ay] of the box centre
    P: np.ndarray          # (N, 6, 6) its covariance

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "x": ((6,), float), "P": ((6, 6), float)}

    def warp(self, m: np.ndarray) -> None:
        """Positions map by m; velocities, accelerations and the covariance by A
        (P' = T P T', T = I3 (x) A)."""
        A, b = m[:, :2], m[:, 2]
        T = np.zeros((6, 6))
        T[0:2, 0:2] = T[2:4, 2:4] = T[4:6, 4:6] = A
        self.x = self.x @ T.T
        self.x[:, :2] += b
        self.P = T @ self.P @ T.T


class FilterBank:
    """Predict and update the filters of the tracks in a TrackTable."""

    def __init__(self, cfg: TrackerConfig) -> None:
        self.cfg = cfg
        self.model = ConstantAcceleration(1.0)   # unit jerk density; scaled per track
        self.kind = cfg.filter
        # Adaptive kinds: one core filter object per track (by uid) on the position rows.
        self._objects: dict[int, GaussianFilter] = {}

    def prior(self, centers: np.ndarray, scale: np.ndarray) -> CentreColumns:
        """(x0, P0) of new tracks before their first detection: centred on it with a
        position spread of the box scale (K,), unknown velocity and acceleration (in box
        scales per second); the first update brings the position to the detection's."""
        cfg = self.cfg
        x0 = np.zeros((len(centers), 6))
        x0[:, :2] = centers
        sd = scale[:, None] * np.array([1.0, 1.0, cfg.init_speed_sigma, cfg.init_speed_sigma,
                                        cfg.init_accel_sigma, cfg.init_accel_sigma])
        P0 = np.zeros((len(centers), 6, 6))
        P0[:, np.arange(6), np.arange(6)] = sd**2
        return CentreColumns(x0, P0)

    def start(self, uids: np.ndarray, x0: np.ndarray, var: np.ndarray, scale: np.ndarray
              ) -> None:
        """Register new tracks (per-track objects for the adaptive kinds, whose prior is
        the first detection with its variance var (K, 2); box scales (K,) px)."""
        if self.kind == "kf":
            return
        cfg = self.cfg
        for u, xi, vi, scale in zip(uids, x0, var, scale, strict=True):
            P0 = np.diag([*vi, *(2 * [(cfg.init_speed_sigma * scale) ** 2]),
                          *(2 * [(cfg.init_accel_sigma * scale) ** 2])])
            position = position_measurement(6, np.sqrt(vi))
            model = ConstantAcceleration(cfg.jerk * scale**2)
            self._objects[int(u)] = make_filter(self.kind, model, position, xi, P0)

    def forget(self, uids: np.ndarray) -> None:
        """Drop the filters of deleted tracks."""
        for u in uids:
            self._objects.pop(int(u), None)

    def _step(self, tracks: TrackTable, i: int, step: Callable[[GaussianFilter], Any]
              ) -> Any:
        """Run `step` on track i's adaptive filter object with the track's (x, P)."""
        f = self._objects[int(tracks.uid[i])]
        f.x, f.P = tracks.x[i].copy(), tracks.P[i].copy()
        out = step(f)
        tracks.x[i], tracks.P[i] = f.x, f.P
        return out

    def predict(self, tracks: TrackTable, dt: float, coasting: np.ndarray | None = None
                ) -> None:
        """Propagate every track over dt (s) with the white-jerk model (seed 001 eqs. 21-23);
        the tracks `coasting` (N,) bool, no detection since the last step, with Singer's
        decaying acceleration instead when `coast_accel_rate` > 0 (models.singer_transition;
        the same white-jerk Q): the one acceleration the detections last estimated is not
        extrapolated as a manoeuvre held for the whole coast."""
        if len(tracks) == 0 or dt <= 0:
            return
        if self.kind == "kf":
            q = self.cfg.jerk * tracks.scale**2
            F = self.model.transition(dt)
            if coasting is not None and self.cfg.coast_accel_rate > 0 and coasting.any():
                F = np.where(coasting[:, None, None],
                             singer_transition(dt, self.cfg.coast_accel_rate), F)
            tracks.x, tracks.P = kf_predict(tracks.x, tracks.P, F,
                                            q[:, None, None] * self.model.Q(dt))
            return
        for i in range(len(tracks)):
            self._step(tracks, i, lambda f: f.predict(dt))

    def update(self, tracks: TrackTable, idx: np.ndarray, z: np.ndarray, H: np.ndarray,
               R: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Update tracks `idx` with the measurement (z, H, R, mask) of measurements.py
        (seed 001 eqs. 24-26). Adaptive kinds take the position rows only. Returns the NIS
        (K,) of each update."""
        if len(idx) == 0:
            return np.zeros(0)
        if self.kind != "kf":
            return self._update_objects(tracks, idx, z)
        nu = z - tracks.x[idx]
        tracks.x[idx], tracks.P[idx], innov = kf_update(tracks.x[idx], tracks.P[idx], nu, H,
                                                        R, mask=mask)
        return innov.nis

    def _update_objects(self, tracks: TrackTable, idx: np.ndarray, z: np.ndarray
                        ) -> np.ndarray:
        nis = np.zeros(len(idx))
        for j, (i, zi) in enumerate(zip(idx, z[:, :2], strict=True)):
            innov = self._step(tracks, i, lambda f, zi=zi: f.update(zi))
            nis[j] = float(innov.nis) if innov is not None else np.nan
        return nis
