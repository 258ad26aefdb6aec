"""Filters as objects with one small surface: predict(dt, u), update(z), x, P.

This module holds the base class, the EKF (which is the linear KF on linear models) and the
iterated EKF; the sigma-point filters are in vtrack.estimation.sigma_filters and every kind
is built by name through vtrack.estimation.registry. Missing measurement cells are NaN.

The EKF's prediction and update are written once. Filters that adapt their noise (the
seed-paper kinds in vtrack.adaptive) supply Q and R through two hooks,
`process_noise(dt)` and `measurement_noise(meas)`, instead of copying the steps.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vtrack.estimation.kalman import Innovation, kf_predict, kf_update
from vtrack.estimation.linalg import EstimationError, cholesky, require_finite, symmetrize
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.options import float_option, int_option


class GaussianFilter:
    """Base: holds the posterior (x, P) and routes present measurement cells to `_update`."""

    kind = "base"

    def __init__(self, motion: MotionModel, measurement: MeasurementModel,
                 x0: np.ndarray, P0: np.ndarray) -> None:
        self.motion = motion
        self.measurement = measurement
        self.x = require_finite(x0, "initial state x0").copy()
        self.P = symmetrize(require_finite(P0, "initial covariance P0"))
        cholesky(self.P, "initial covariance P0")
        self.last: Innovation | None = None

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        raise NotImplementedError

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        raise NotImplementedError

    def update(self, z: np.ndarray) -> Innovation | None:
        """Update with the finite cells of z (NaN = missing); all missing = no update."""
        z = np.asarray(z, dtype=float)
        if np.any(np.isinf(z)):
            raise EstimationError("measurement has infinite entries")
        present = np.isfinite(z)
        self.last = None
        if present.any():
            self.last = self._update(self.measurement.subset(present), z[present])
        return self.last

    def step(self, dt: float, z: np.ndarray, u: np.ndarray | None = None) -> Innovation | None:
        """One predict over dt, then the update with z."""
        self.predict(dt, u)
        return self.update(z)


class ExtendedKalmanFilter(GaussianFilter):
    """EKF (seed 000 eqs. 7-9): F at the posterior, H at the prior, Joseph-form update.

    With linear models it is exactly the linear KF (kind 'kf'). Subclasses that adapt the
    noise override the hooks `process_noise` and `measurement_noise`."""

    kind = "ekf"

    def process_noise(self, dt: float) -> np.ndarray:
        """The Q of the next prediction (hook; the model's Q(dt) here)."""
        return self.motion.Q(dt)

    def measurement_noise(self, meas: MeasurementModel) -> np.ndarray:
        """The R of the next update for the rows `meas` holds (hook; the model's R here)."""
        return meas.R

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        """x- = f(x, dt, u),  P- = F P F' + Q,  F = df/dx at x  (kalman.kf_predict)."""
        F = self.motion.F(self.x, dt, u)
        self.x, self.P = kf_predict(self.x, self.P, F, self.process_noise(dt),
                                    fx=self.motion.f(self.x, dt, u))

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        """nu = wrap(z - h(x-)), H = dh/dx at x-, Joseph-form update (kalman.kf_update)."""
        nu = meas.residual(z, meas.h(self.x))
        self.x, self.P, info = kf_update(self.x, self.P, nu, meas.H(self.x),
                                         self.measurement_noise(meas))
        return info


# ------------------------------------------------------------------ iterated updates

Linearisation = tuple[np.ndarray, np.ndarray, np.ndarray | None]
"""h(x) ~ y + A (x - m) about a point m, with error covariance Omega (None: zero)."""


def iterated_update(motion: MotionModel, meas: MeasurementModel, x_prior: np.ndarray,
                    P_prior: np.ndarray, z: np.ndarray, R: np.ndarray,
                    linearise: Callable[[np.ndarray, np.ndarray], Linearisation],
                    max_iterations: int, tolerance: float,
                    cost: Callable[[np.ndarray], float] | None = None
                    ) -> tuple[np.ndarray, np.ndarray, Innovation, int]:
    """The update of the prior (x-, P-) relinearised at its own result until it settles.

    Iterate i = 1, 2, ... from (m_0, P_0) = (x-, P-): linearise h about the current iterate,
    h(x) ~ y_i + A_i (x - m_i) with error covariance Omega_i (`linearise(m_i, P_i)`), and
    update the PRIOR with that linear model (Joseph form, kalman.kf_update):

        nu_i = wrap(z - y_i) + A_i (m_i - x-)        (= z - [y_i + A_i (x- - m_i)])
        m_{i+1}, P_{i+1} = kf_update(x-, P-, nu_i, A_i, R + Omega_i)

    With a `cost` (the iterated EKF's MAP cost) the step d = m_{i+1} - m_i is halved until
    the cost does not increase (Skoglund, Hendeby & Axehill 2015: a Gauss-Newton step can
    overshoot), and iterating stops when no such step is found. Stop when the step taken
    (angles wrapped) is small in the new posterior's own metric, sqrt(d' P_{i+1}^-1 d) <=
    tolerance, or after max_iterations. The first full step is the plain EKF (or UKF/CKF)
    update. The result's covariance and innovation are those of the last linearisation.
    Returns (x, P, innovation, iterations done).
    """
    m, P = x_prior, P_prior
    for i in range(1, max_iterations + 1):
        A, y, Omega = linearise(m, P)
        nu = meas.residual(z, y) + A @ motion.residual(m, x_prior)
        x, P, info = kf_update(x_prior, P_prior, nu, A, R if Omega is None else R + Omega)
        d = motion.residual(x, m)
        if cost is not None:
            x, d = _halve_until_no_increase(cost, m, x, d)
            if x is m:
                break
        m = x
        if i > 1 and float(d @ np.linalg.solve(P, d)) <= tolerance**2:
            break
    return m, P, info, i


def _halve_until_no_increase(cost: Callable[[np.ndarray], float], m: np.ndarray,
                             x: np.ndarray, d: np.ndarray, halvings: int = 10
                             ) -> tuple[np.ndarray, np.ndarray]:
    """The full step (x, d) if cost(x) <= cost(m), else m + d/2^j for the first j <= halvings
    that does not increase the cost; (m, 0) if none does."""
    c0 = cost(m)
    if cost(x) <= c0:
        return x, d
    for _ in range(halvings):
        d = 0.5 * d
        if cost(m + d) <= c0:
            return m + d, d
    return m, np.zeros_like(d)


MAX_ITERATIONS = 30     # defaults of the iterated kinds (iekf, iplf); see docs/EXPERIMENTS.md
TOLERANCE = 1e-4


def iteration_options(max_iterations: object, tolerance: object) -> tuple[int, float]:
    """Validated (max_iterations: integer >= 1, tolerance: number > 0) of an iterated kind."""
    return (int_option("max_iterations", max_iterations, 1),
            float_option("tolerance", tolerance, 0.0))


class IteratedExtendedKalmanFilter(ExtendedKalmanFilter):
    """Iterated EKF (Bell & Cathey 1993: the Gauss-Newton maximum a posteriori update).

    The EKF's prediction; the update relinearises h at its own result (iterated_update with
    A_i = H(m_i), y_i = h(m_i), Omega_i = 0):

        m_{i+1} = x- + K_i (z - h(m_i) - H_i (x- - m_i)),  K_i = P- H_i' (H_i P- H_i' + R)^-1

    a step that would increase the MAP cost (x - x-)' P-^-1 (x - x-) + r' R^-1 r,
    r = wrap(z - h(x)), being halved (line search), and P = (I - K H) P- (I - K H)' + K R K'
    with H = H(m) at the last linearisation point. On a linear measurement the second
    iteration repeats the first (the KF). `iterations` holds the count of the last update.

    Options: max_iterations (default 30), tolerance (default 1e-4: the last step below
    1e-4 posterior standard deviations).
    """

    kind = "iekf"

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, max_iterations: int = MAX_ITERATIONS,
                 tolerance: float = TOLERANCE) -> None:
        super().__init__(motion, measurement, x0, P0)
        self.max_iterations, self.tolerance = iteration_options(max_iterations, tolerance)
        self.iterations = 0

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        R = self.measurement_noise(meas)
        x_prior = self.x
        Lp, Lr = cholesky(self.P, "predicted covariance"), cholesky(R, "measurement noise R")

        def linearise(m: np.ndarray, P: np.ndarray) -> Linearisation:
            return meas.H(m), meas.h(m), None

        def cost(m: np.ndarray) -> float:
            """MAP cost, up to a factor 1/2: |x - x-|^2_{P-} + |wrap(z - h(x))|^2_R."""
            a = np.linalg.solve(Lp, self.motion.residual(m, x_prior))
            b = np.linalg.solve(Lr, meas.residual(z, meas.h(m)))
            return float(a @ a + b @ b)

        self.x, self.P, info, self.iterations = iterated_update(
            self.motion, meas, x_prior, self.P, z, R, linearise, self.max_iterations,
            self.tolerance, cost)
        return info
