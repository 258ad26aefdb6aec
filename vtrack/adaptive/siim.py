"""Seed 004's SIIM fuzzy-logic EKF, kind siim-ekf (Chai 2016; SEEDS 6.2).

A 2-input, 4-rule "simplified indirect inference" fuzzy system gives alpha in [-1, 1] from
the relative covariance-trace drop and the relative residual of each update; then
Q <- (1 - gamma alpha) Q and R <- (1 + gamma alpha) R, supplied to the core EKF through its
Q/R hooks (vtrack.estimation.filters.ExtendedKalmanFilter).
"""

from __future__ import annotations

import numpy as np

from vtrack.estimation.filters import ExtendedKalmanFilter
from vtrack.estimation.kalman import Innovation
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.options import float_option
from vtrack.estimation.registry import register


def siim_pa(x: np.ndarray) -> np.ndarray:
    """Monotone linear input membership PA(x) = (x + 1)/2 on [-1, 1] (seed 004 eq. 13, L = 1)."""
    return (np.clip(x, -1.0, 1.0) + 1.0) / 2.0


def siim_pc_inv(w: np.ndarray, M: float = 1.0) -> np.ndarray:
    """Inverse of the output term PC (eq. 16, reconstructed): M(-2 + sqrt(21.25 - (w-4.5)^2)),
    an arc through (0, -M) and (1, +M). NC^-1 = -PC^-1."""
    return M * (-2.0 + np.sqrt(21.25 - (np.asarray(w, dtype=float) - 4.5) ** 2))


SIIM_RULES: tuple[tuple[int, str, int], ...] = (
    # (input index, input term, output sign: +1 = PC, -1 = NC)
    (0, "PA", +1),   # R1: if x1 is PA then u11 is PC
    (0, "NA", -1),   # R2: if x1 is NA then u12 is NC
    (1, "PA", +1),   # R3: if x2 is PA then u21 is PC
    (1, "NA", -1),   # R4: if x2 is NA then u22 is NC
)


def siim_alpha(x1: np.ndarray, x2: np.ndarray, M: float = 1.0) -> np.ndarray:
    """SIIM output alpha = sum w_i u_i / sum w_i with u_i read off the inverse output term at
    the firing degree w_i (eqs. 17-19). Equals (g(x1) + g(x2))/2, g odd and monotone,
    g(0) = 0, g(+-1) = +-M (SEEDS 6.2)."""
    xs = (np.asarray(x1, dtype=float), np.asarray(x2, dtype=float))
    num = 0.0
    den = 0.0
    for i, term, sign in SIIM_RULES:
        pa = siim_pa(xs[i])
        w = pa if term == "PA" else 1.0 - pa
        num = num + w * sign * siim_pc_inv(w, M)
        den = den + w
    return num / den


class SIIMExtendedKalmanFilter(ExtendedKalmanFilter):
    """Seed 004's SIIM fuzzy-logic EKF (Chai 2016), SEEDS 6.2.

    After each (Joseph-form) EKF update:
        x1 = (tr P- - tr P) / tr P-                 (in [0, 1])
        x2 = mean_j clip(nu_j / max(|z_j|, sqrt(R_nom,jj)), -1, 1)   (nu wrapped for angles)
        alpha = SIIM(x1, x2) in [-1, 1]  (normalised universe, M = 1 in eq. 16)
        Q <- (1 - gamma alpha) Q,  R <- (1 + gamma alpha) R,  both clamped to
        [1e-3, 1e3] x nominal (eq. 20 with gamma = the paper's M).
    The x2 denominator is guarded by the measurement's nominal std (relative residuals below
    the noise level are not meaningful); for a scalar measurement the mean is the plain x2.
    """

    kind = "siim-ekf"

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, gamma: float = 1e-4, lo: float = 1e-3, hi: float = 1e3
                 ) -> None:
        super().__init__(motion, measurement, x0, P0)
        self.gamma = float_option("gamma", gamma)
        if not 0.0 <= self.gamma < 1.0:
            raise ValueError(f"siim-ekf gamma must be in [0, 1), got {gamma}")
        self.lo, self.hi = float(lo), float(hi)
        runs = self.x.shape[:-1]          # () for one track: the scales are then numbers
        self.q_scale: float | np.ndarray = np.ones(runs) if runs else 1.0
        self.r_scale: float | np.ndarray = np.ones(runs) if runs else 1.0
        self.alpha: float | np.ndarray = np.zeros(runs) if runs else 0.0

    def process_noise(self, dt: float) -> np.ndarray:
        """The scaled process noise q_scale Q."""
        return np.asarray(self.q_scale)[..., None, None] * self.motion.Q(dt)

    def measurement_noise(self, meas: MeasurementModel) -> np.ndarray:
        """The scaled measurement noise r_scale R."""
        return np.asarray(self.r_scale)[..., None, None] * meas.R

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        tr_prior = np.trace(self.P, axis1=-2, axis2=-1)
        info = super()._update(meas, z)
        with np.errstate(divide="ignore", invalid="ignore"):
            x1 = np.where(tr_prior > 0,
                          (tr_prior - np.trace(self.P, axis1=-2, axis2=-1)) / tr_prior, 0.0)
        denom = np.maximum(np.abs(z), np.sqrt(np.diag(meas.R)))
        x2 = np.mean(np.clip(info.nu / denom, -1.0, 1.0), axis=-1)
        alpha = siim_alpha(x1, x2)
        q_scale = np.clip(self.q_scale * (1.0 - self.gamma * alpha), self.lo, self.hi)
        r_scale = np.clip(self.r_scale * (1.0 + self.gamma * alpha), self.lo, self.hi)
        if np.ndim(alpha):
            self.alpha, self.q_scale, self.r_scale = alpha, q_scale, r_scale
        else:
            self.alpha, self.q_scale, self.r_scale = float(alpha), float(q_scale), float(r_scale)
        return info


@register("siim-ekf", ("gamma",))
def _siim_ekf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
              **opts: float) -> SIIMExtendedKalmanFilter:
    """siim-ekf: option gamma (the paper's M; default 1e-4, seed 004 scenario 2)."""
    return SIIMExtendedKalmanFilter(motion, meas, x0, P0, **opts)
