"""Adaptive EKF kinds of seed 000: ANKF1 (innovation-based adaptive estimation, IAE) and ANKF2
(adaptive fading with measurement-noise scaling, AFKF).

Registered into the core's registry (vtrack.estimation.registry) on import
(`vtrack.filter_kinds.make_filter("ankf1", ...)`, `[filter] kind = "ankf1"` in `vtrack filter`).

The seed (Khadour et al. 2019) takes both from Jwo & Weng (2008) but its flowcharts are lost;
this is the reconstruction of SEEDS.md section 2.4 [A], from Mohamed & Schwarz (1999, IAE)
and Xia et al. (1994, fading factors). Both filters are the core EKF
(vtrack.estimation.filters.ExtendedKalmanFilter: its prediction, and the core
`kalman.kf_update` (Joseph form) with an adapted R and, for ANKF2, a faded prior P-).

Common part (SEEDS 1.6): every wrapped innovation nu_k = wrap(z_k - h(m-)) of a step with a
FULL measurement vector is pushed into a ring buffer of the last N innovations, and

    C_hat_k = (1/N) sum_{j=k-N+1..k} nu_j nu_j'         (no mean removal)
    C_k     = H P- H' + R_nom                            (theoretical innovation covariance)

Until N innovations exist the filters are the plain EKF.

Missing measurement cells (NaN in z, see GaussianFilter.update): a step with only some cells
present does not enter the window (the window statistics need one fixed measurement vector);
it is updated with the current adapted noise restricted to the present rows (ANKF1: the last
R_hat; ANKF2: the last lambda_R, and no fading, lambda_P = 1). A step with no cell present only
predicts. Before the first adaptation such steps use R_nom, exactly like the EKF.
"""

from __future__ import annotations

import numpy as np

from vtrack.adaptive.innovation_windows import InnovationCovarianceWindow
from vtrack.estimation.filters import ExtendedKalmanFilter
from vtrack.estimation.kalman import Innovation, kf_update
from vtrack.estimation.linalg import symmetrize
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.options import bool_option, float_option, int_option
from vtrack.estimation.registry import register

__all__ = [
    "iae_measurement_noise",
    "fading_factors",
    "scale_noise",
    "ankf1_update",
    "ankf2_update",
    "InnovationAdaptiveEKF",
    "FadingAdaptiveEKF",
]


# ------------------------------------------------------------------------------ pieces


def iae_measurement_noise(C_hat: np.ndarray, HPH: np.ndarray, R_nom: np.ndarray,
                          r_floor: float) -> np.ndarray:
    """IAE estimate of R (Mohamed & Schwarz 1999; SEEDS 2.4, ANKF1):

        R_hat = diag(C_hat - H P- H'),  each entry floored at r_floor * diag(R_nom)

    Only the diagonal is kept and it is floored because C_hat - H P- H' can be negative or tiny
    early on, which makes the filter overconfident (SEEDS 2.6). Returns the diagonal (..., m).
    """
    d = np.diagonal(C_hat - HPH, axis1=-2, axis2=-1)
    floor = r_floor * np.diagonal(R_nom, axis1=-2, axis2=-1)
    return np.maximum(d, floor)


def fading_factors(C_hat: np.ndarray, C: np.ndarray, lambda_max: float,
                   ratio_min: float, ratio_max: float,
                   multiple: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Fading and noise-scaling factors of ANKF2 (seed 000 section 4 d; SEEDS 2.4):

        ratio    = tr(C_hat) / tr(C)
        lambda_P = clip(ratio, 1, lambda_max)             (seed: max{1, tr C_hat / tr C})
        lambda_R = clip(ratio, ratio_min, ratio_max)      ("single factor", every row), or
        lambda_R,jj = clip(C_hat_jj / C_jj, ...)          ("multiple factors")

    Returns lambda_P (...,) and lambda_R (..., m).
    """
    ratio = np.trace(C_hat, axis1=-2, axis2=-1) / np.trace(C, axis1=-2, axis2=-1)
    lam_P = np.clip(ratio, 1.0, lambda_max)
    m = C.shape[-1]
    if multiple:
        raw = np.diagonal(C_hat, axis1=-2, axis2=-1) / np.diagonal(C, axis1=-2, axis2=-1)
    else:
        raw = np.repeat(np.asarray(ratio)[..., None], m, axis=-1)
    return lam_P, np.clip(raw, ratio_min, ratio_max)


def scale_noise(R: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """R_bar = lambda_R R, written D^1/2 R D^1/2 with D = diag(lambda_R) so that it stays
    symmetric for a full R (equal to lambda_jj R_jj for the diagonal R of the seeds)."""
    s = np.sqrt(lam)
    return R * s[..., :, None] * s[..., None, :]


def _diag_embed(d: np.ndarray) -> np.ndarray:
    return d[..., :, None] * np.eye(d.shape[-1])


def _per_run(M: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A copy of the matrix M for each run of the state x (..., n) (M itself for one track)."""
    return np.broadcast_to(M, x.shape[:-1] + M.shape).copy()


def ankf1_update(x: np.ndarray, P: np.ndarray, nu: np.ndarray, H: np.ndarray,
                 R_nom: np.ndarray, window: InnovationCovarianceWindow, r_floor: float, adapt_r: bool,
                 adapt_q: bool, R_hat: np.ndarray | None
                 ) -> tuple[np.ndarray, np.ndarray, Innovation, np.ndarray,
                            np.ndarray | None, np.ndarray | None]:
    """One ANKF1 update with a FULL measurement vector (SEEDS 2.4); arrays may carry leading
    batch axes (one window of that batch shape). Pushes nu; once the window is full
    R_hat = iae_measurement_noise(...) (adapt_r) and Q_hat = K C_hat K' (adapt_q); the update
    is kalman.kf_update with diag(R_hat) (or R_nom before the first estimate).

    Returns (x, P, info, R used, R_hat (diag) or the previous one, Q_hat or None)."""
    window.push(nu)
    C_hat = None
    if window.full:
        C_hat = window.covariance()
        if adapt_r:
            R_hat = iae_measurement_noise(C_hat, H @ P @ np.swapaxes(H, -1, -2), R_nom, r_floor)
    R = _diag_embed(R_hat) if (adapt_r and R_hat is not None) else R_nom
    x, P, info = kf_update(x, P, nu, H, R)
    Q_hat = None
    if adapt_q and C_hat is not None:
        Q_hat = symmetrize(info.K @ C_hat @ np.swapaxes(info.K, -1, -2))
    return x, P, info, R, R_hat, Q_hat


def ankf2_update(x: np.ndarray, Pprop: np.ndarray, Q: np.ndarray, nu: np.ndarray,
                 H: np.ndarray, R_nom: np.ndarray, window: InnovationCovarianceWindow,
                 lambda_max: float, ratio_min: float, ratio_max: float, multiple: bool,
                 fade_prior: bool, lambda_R: np.ndarray | None
                 ) -> tuple[np.ndarray, np.ndarray, Innovation, np.ndarray, np.ndarray,
                            np.ndarray | None]:
    """One ANKF2 update with a FULL measurement vector (SEEDS 2.4); arrays may carry leading
    batch axes. Pushes nu; once the window is full, C = H (Pprop + Q) H' + R_nom,
    (lambda_P, lambda_R) = fading_factors(C_hat, C, ...), P- = lambda_P Pprop + Q
    (fade_prior: lambda_P (Pprop + Q)) and R_bar = lambda_R R_nom; then kalman.kf_update.
    Before that (or with lambda_max = 1) it is the EKF update of P- = Pprop + Q.

    Returns (x, P, info, R used, lambda_P, lambda_R or the previous one)."""
    P_prior = symmetrize(Pprop + Q)
    lam_P = np.ones(np.shape(x)[:-1])
    window.push(nu)
    if window.full:
        C = symmetrize(H @ P_prior @ np.swapaxes(H, -1, -2) + R_nom)
        lam_P, lambda_R = fading_factors(window.covariance(), C, lambda_max, ratio_min,
                                         ratio_max, multiple)
        lp = np.asarray(lam_P)[..., None, None]
        P_prior = symmetrize(lp * (Pprop + Q) if fade_prior else lp * Pprop + Q)
    R = R_nom if lambda_R is None else scale_noise(R_nom, lambda_R)
    x, P, info = kf_update(x, P_prior, nu, H, R)
    return x, P, info, R, lam_P, lambda_R


# ------------------------------------------------------------------------------ ANKF1


class InnovationAdaptiveEKF(ExtendedKalmanFilter):
    """ANKF1 = EKF + innovation-based adaptive estimation (seed 000 Fig. 1; SEEDS 2.4 [A]).

    Per update, once the window holds N innovations:

        R_hat_k = diag(C_hat_k - H P- H'), floored at r_floor * diag(R_nom)   (adapt_r)
        x, P    = Joseph-form update with R_hat_k                           (kalman.kf_update)
        Q_hat_k = K_k C_hat_k K_k'  replaces Q in the next prediction       (adapt_q)

    Options (all optional):
        window  (int, default 20)      N, the innovation window length
        r_floor (float, default 0.01)  floor of R_hat as a fraction of diag(R_nom), > 0
        adapt_r (bool, default true)   estimate R (the IAE of the seed)
        adapt_q (bool, default false)  also estimate Q (Mohamed & Schwarz); SEEDS 2.5 shows it
                                       hurts in seed 000's scenario 3a

    Diagnostics after each update: `R_used` (the R of the last update), `R_hat` (diagonal of
    the latest estimate or None), `Q_hat` (or None), `adapted` (whether the last update used
    the window).
    """

    kind = "ankf1"

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, window: int = 20, r_floor: float = 0.01,
                 adapt_r: bool = True, adapt_q: bool = False) -> None:
        super().__init__(motion, measurement, x0, P0)
        self.window = InnovationCovarianceWindow(int_option("window", window, 1),
                                                 self.x.shape[:-1] + (measurement.m,))
        self.r_floor = float_option("r_floor", r_floor, 0.0)
        self.adapt_r = bool_option("adapt_r", adapt_r)
        self.adapt_q = bool_option("adapt_q", adapt_q)
        self.R_hat: np.ndarray | None = None
        self.Q_hat: np.ndarray | None = None
        self.R_used: np.ndarray = _per_run(measurement.R, self.x)
        self.adapted = False

    def process_noise(self, dt: float) -> np.ndarray:
        """With adapt_q the latest Q_hat replaces the model Q."""
        return self.motion.Q(dt) if self.Q_hat is None else self.Q_hat

    def measurement_noise(self, meas: MeasurementModel) -> np.ndarray:
        """The latest R_hat on the rows of `meas` (R_nom before the first estimate): what a
        step with only some cells present is updated with."""
        if self.adapt_r and self.R_hat is not None:
            return _diag_embed(self.R_hat[..., meas.row_indices()])
        return meas.R

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        if meas.m < self.measurement.m:           # partial vector: last R_hat, no window
            self.R_used, self.adapted = self.measurement_noise(meas), False
            return super()._update(meas, z)
        H = meas.H(self.x)                        # full vector: the window step
        nu = meas.residual(z, meas.h(self.x))
        self.x, self.P, info, self.R_used, self.R_hat, Q_hat = ankf1_update(
            self.x, self.P, nu, H, meas.R, self.window, self.r_floor, self.adapt_r,
            self.adapt_q, self.R_hat)
        self.adapted = self.window.full
        if Q_hat is not None:
            self.Q_hat = Q_hat
        return info


# ------------------------------------------------------------------------------ ANKF2


class FadingAdaptiveEKF(ExtendedKalmanFilter):
    """ANKF2 = EKF + adaptive fading with measurement-noise scaling (seed 000 Fig. 2 and
    section 4 a-d; SEEDS 2.4 [A]).

    The prediction keeps the propagated part Pprop = F P F' apart from Q. Per update, once the
    window holds N innovations (C computed with the unfaded prior P- = Pprop + Q):

        ratio    = tr(C_hat_k) / tr(C_k)
        lambda_P = clip(ratio, 1, lambda_max)
        P-       = lambda_P Pprop + Q          (fade_prior: lambda_P (Pprop + Q))
        R_bar    = lambda_R R_nom,  lambda_R = clip(ratio, ratio_min, ratio_max)
                   (multiple_factors: lambda_R,jj = clip(C_hat_jj / C_jj, ...))
        x, P     = Joseph-form update with P-, R_bar                        (kalman.kf_update)

    Fading compounds from step to step, so lambda_max is kept low (SEEDS 2.6: an AFKF capped
    at 10 exploded when R was underestimated).

    Options (all optional):
        window           (int, default 20)     N, the innovation window length
        lambda_max       (float, default 1.5)  cap of the fading factor, >= 1
        ratio_min        (float, default 0.01) lower clip of lambda_R, > 0
        ratio_max        (float, default 100)  upper clip of lambda_R, >= ratio_min
        multiple_factors (bool, default false) one lambda_R per measurement row
        fade_prior       (bool, default false) fade Pprop + Q instead of Pprop alone

    Diagnostics after each update: `lambda_P` (float; (R,) for a stack of runs), `lambda_R`
    ((..., m) or None), `R_used`,
    `adapted`.
    """

    kind = "ankf2"

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, window: int = 20, lambda_max: float = 1.5,
                 ratio_min: float = 0.01, ratio_max: float = 100.0,
                 multiple_factors: bool = False, fade_prior: bool = False) -> None:
        super().__init__(motion, measurement, x0, P0)
        self.window = InnovationCovarianceWindow(int_option("window", window, 1),
                                                 self.x.shape[:-1] + (measurement.m,))
        self.lambda_max = float_option("lambda_max", lambda_max, 1.0, strict=False)
        self.ratio_min = float_option("ratio_min", ratio_min, 0.0)
        self.ratio_max = float_option("ratio_max", ratio_max, self.ratio_min, strict=False)
        self.multiple_factors = bool_option("multiple_factors", multiple_factors)
        self.fade_prior = bool_option("fade_prior", fade_prior)
        self._Pprop: np.ndarray | None = None
        self._Q: np.ndarray | None = None
        self.lambda_P: float | np.ndarray = 1.0
        self.lambda_R: np.ndarray | None = None
        self.R_used: np.ndarray = _per_run(measurement.R, self.x)
        self.adapted = False

    def process_noise(self, dt: float) -> np.ndarray:
        """Zero: the EKF prediction gives the propagated part Pprop = F P F'; `predict` adds
        Q afterwards and keeps both for the fading."""
        return np.zeros((self.motion.n, self.motion.n))

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        """The EKF prediction of Pprop = F P F', then P- = Pprop + Q (both remembered)."""
        super().predict(dt, u)
        self._Pprop, self._Q = self.P, self.motion.Q(dt)
        self.P = symmetrize(self._Pprop + self._Q)

    def measurement_noise(self, meas: MeasurementModel) -> np.ndarray:
        """R_nom scaled by the latest lambda_R on the rows of `meas` (what a step with only
        some cells present is updated with)."""
        if self.lambda_R is None:
            return meas.R
        return scale_noise(meas.R, self.lambda_R[..., meas.row_indices()])

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        if meas.m < self.measurement.m:           # partial vector: last lambda_R, no fading
            self.R_used, self.lambda_P, self.adapted = self.measurement_noise(meas), 1.0, False
            info = super()._update(meas, z)
        else:                                     # full vector: the window step
            if self._Pprop is None:               # no prediction since the last update:
                Pprop, Q, lam_max = self.P, np.zeros_like(self.P), 1.0   # nothing to fade
            else:
                Pprop, Q, lam_max = self._Pprop, self._Q, self.lambda_max
            H = meas.H(self.x)
            nu = meas.residual(z, meas.h(self.x))
            self.x, self.P, info, self.R_used, lam_P, self.lambda_R = ankf2_update(
                self.x, Pprop, Q, nu, H, meas.R, self.window, lam_max, self.ratio_min,
                self.ratio_max, self.multiple_factors, self.fade_prior, self.lambda_R)
            self.lambda_P = lam_P if np.ndim(lam_P) else float(lam_P)
            self.adapted = self.window.full
        self._Pprop = None     # fading applies once per prediction
        return info


# ---------------------------------------------------------------------------- registry

_ANKF1_OPTIONS = ("window", "r_floor", "adapt_r", "adapt_q")
_ANKF2_OPTIONS = ("window", "lambda_max", "ratio_min", "ratio_max", "multiple_factors",
                  "fade_prior")


@register("ankf1", options=_ANKF1_OPTIONS)
def _ankf1(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
           **options: float) -> InnovationAdaptiveEKF:
    """EKF + IAE of R (optionally Q); options: window, r_floor, adapt_r, adapt_q."""
    return InnovationAdaptiveEKF(motion, meas, x0, P0, **options)


@register("ankf2", options=_ANKF2_OPTIONS)
def _ankf2(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
           **options: float) -> FadingAdaptiveEKF:
    """EKF + adaptive fading and R scaling; options: window, lambda_max, ratio_min, ratio_max,
    multiple_factors, fade_prior."""
    return FadingAdaptiveEKF(motion, meas, x0, P0, **options)
