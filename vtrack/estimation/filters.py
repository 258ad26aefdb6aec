"""Filters as objects with one small surface: predict(dt, u), update(z), x, P.

This module holds the base class, the EKF (which is the linear KF on linear models) and the
iterated EKF (its iterations in vtrack.estimation.iterated); the sigma-point filters are in
vtrack.estimation.sigma_filters and every kind is built by name through
vtrack.estimation.registry. Missing measurement cells are NaN.

A filter holds one track (x (n,), P (n, n)) or a stack of R runs (x (R, n), P (R, n, n)),
stepped by the same code (GaussianFilter). The EKF's prediction and update are written once. Filters that adapt their noise (the
seed-paper kinds in vtrack.adaptive) supply Q and R through two hooks,
`process_noise(dt)` and `measurement_noise(meas)`, instead of copying the steps.
"""

from __future__ import annotations

import numpy as np

from vtrack.estimation.iterated import (
    DAMPED,
    MAX_ITERATIONS,
    TOLERANCE,
    Linearisation,
    iterated_update,
    iteration_options,
)
from vtrack.estimation.kalman import Innovation, kf_predict, kf_update
from vtrack.estimation.linalg import EstimationError, cholesky, require_finite, symmetrize
from vtrack.estimation.models import MeasurementModel, MotionModel


class GaussianFilter:
    """Base: holds the posterior (x, P) and routes present measurement cells to `_update`.

    One track has x (n,), P (n, n). Built with a stack of initial states x0 (R, n) (P0 (n, n)
    shared or (R, n, n)), the filter runs R tracks at once (the Monte Carlo runs of
    vtrack.estimation.montecarlo): every step is the same code with a leading run axis, and
    z is (R, m). Kinds that cannot do that set `batched = False`."""

    kind = "base"
    batched = True

    def __init__(self, motion: MotionModel, measurement: MeasurementModel,
                 x0: np.ndarray, P0: np.ndarray) -> None:
        self.motion = motion
        self.measurement = measurement
        self.x = require_finite(x0, "initial state x0").copy()
        P0 = require_finite(P0, "initial covariance P0")
        self.P = symmetrize(np.broadcast_to(P0, self.x.shape + self.x.shape[-1:]).copy())
        cholesky(self.P, "initial covariance P0")
        self.last: Innovation | None = None

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        raise NotImplementedError

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        raise NotImplementedError

    def update(self, z: np.ndarray) -> Innovation | None:
        """Update with the finite cells of z (NaN = missing); all missing = no update. The
        runs of a stack z (R, m) must miss the same cells (the harness groups them so)."""
        z = np.asarray(z, dtype=float)
        if np.any(np.isinf(z)):
            raise EstimationError("measurement has infinite entries")
        present = np.isfinite(z).reshape(-1, z.shape[-1])
        if np.any(present != present[0]):
            raise EstimationError("the runs of a batch miss different measurement cells")
        self.last = None
        if present[0].any():
            self.last = self._update(self.measurement.subset(present[0]), z[..., present[0]])
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


class IteratedExtendedKalmanFilter(ExtendedKalmanFilter):
    """Iterated EKF (Bell & Cathey 1993: the Gauss-Newton maximum a posteriori update),
    damped by Levenberg-Marquardt (the LM-IEKF of Skoglund, Hendeby & Axehill 2015).

    The EKF's prediction; the update relinearises h at its own result (iterated.iterated_update
    with A_i = H(m_i), y_i = h(m_i), Omega_i = 0):

        m_{i+1} = x- + K_i (z - h(m_i) - H_i (x- - m_i)),  K_i = P- H_i' (H_i P- H_i' + R)^-1

    and P = (I - K H) P- (I - K H)' + K R K' (Joseph form) with H at the last linearisation.
    Damped (the default), a step is kept only if it lowers

        V(x) = (x - x-)' P-^-1 (x - x-) + r' R^-1 r + log det(H(x) P- H(x)' + R),
        r = wrap(z - h(x))

    (the MAP cost plus the log det that keeps it out of the spike next to a bearing sensor;
    iterated.merit) and is otherwise retried with Levenberg-Marquardt damping
    (iterated.damped_step); the first step is the EKF update. On a linear measurement the second iteration repeats the first
    (the KF). `iterations` holds the count of the last update.

    Options: max_iterations (default 30), tolerance (default 1e-4: the last step below 1e-4
    posterior standard deviations), damped (default true; false: plain Gauss-Newton).
    With a stack of runs `iterations` holds one count per run.
    """

    kind = "iekf"

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, max_iterations: int = MAX_ITERATIONS,
                 tolerance: float = TOLERANCE, damped: bool = DAMPED) -> None:
        super().__init__(motion, measurement, x0, P0)
        self.max_iterations, self.tolerance, self.damped = iteration_options(
            max_iterations, tolerance, damped)
        self.iterations: int | np.ndarray = 0

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        def linearise(m: np.ndarray, P: np.ndarray) -> Linearisation:
            return meas.H(m), meas.h(m), None

        self.x, self.P, info, self.iterations = iterated_update(
            self.motion, meas, self.x, self.P, z, self.measurement_noise(meas), linearise,
            self.max_iterations, self.tolerance, self.damped, uses_covariance=False)
        return info
