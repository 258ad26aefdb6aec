"""Sigma-point filters: UKF and CKF share one step and differ only in their SigmaPointRule;
the iterated posterior linearisation filter (IPLF) iterates that update; the square-root UKF
and seed 002's cube-root variant share one square-root step and differ only in the root.
Missing measurement cells are NaN (GaussianFilter.update). Every filter here takes a stack
of runs (a leading axis, GaussianFilter).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vtrack.estimation.filters import GaussianFilter
from vtrack.estimation.iterated import (
    DAMPED,
    MAX_ITERATIONS,
    TOLERANCE,
    Linearisation,
    iterated_update,
    iteration_options,
)
from vtrack.estimation.kalman import Innovation
from vtrack.estimation.linalg import (
    EstimationError,
    NotPositiveDefiniteError,
    cholesky,
    cholesky_each,
    cholupdate_each,
    spd_root,
    symmetrize,
    tria,
)
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.sigma_points import SigmaPointRule


def weighted_mean(Y: np.ndarray, Wm: np.ndarray, ref: np.ndarray,
                  residual: Callable[[np.ndarray, np.ndarray], np.ndarray]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Sigma-point mean taken relative to a reference, ybar = ref + sum Wm_i r(Y_i, ref), and the
    deviations r(Y_i, ybar). With wrapped residuals this averages angles across +-pi (SEEDS 1.4).
    Y (..., N, d), ref (..., d)."""
    mean = ref + Wm @ residual(Y, ref[..., None, :])
    return mean, residual(Y, mean[..., None, :])


def _T(a: np.ndarray) -> np.ndarray:
    return np.swapaxes(a, -1, -2)


def _inputs_of_points(u: np.ndarray | None) -> np.ndarray | None:
    """The input u (..., p) of a track or stack, shaped to broadcast over its sigma points."""
    return None if u is None else np.asarray(u, dtype=float)[..., None, :]


class SigmaPointKalmanFilter(GaussianFilter):
    """UKF (seed 000 eqs. 10-13) or CKF (eqs. 14-24), depending on the rule.

    Additive noise: P- = sum Wc dX dX' + Q; update S = sum Wc dY dY' + R, Pxy = sum Wc dX dY',
    K = Pxy S^-1, P = P- - K S K'."""

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, rule: SigmaPointRule, kind: str = "ukf") -> None:
        super().__init__(motion, measurement, x0, P0)
        self.rule = rule
        self.kind = kind

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        X = self.rule.points(self.x, cholesky(self.P, "state covariance"))
        Xp = self.motion.f(X, dt, _inputs_of_points(u))
        ref = self.motion.f(self.x, dt, u)
        self.x, dX = weighted_mean(Xp, self.rule.Wm, ref, self.motion.residual)
        self.P = symmetrize((_T(dX) * self.rule.Wc) @ dX + self.motion.Q(dt))

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        ybar, Pxy, Pyy = sigma_moments(self.rule, self.motion, meas, self.x, self.P)
        S = symmetrize(Pyy + meas.R)
        L = cholesky(S, "innovation covariance S")
        # K = Pxy S^-1 through the factor. numpy's solve, not scipy's solve_triangular: the
        # latter can take milliseconds per tiny call under a multi-threaded OpenBLAS.
        K = _T(np.linalg.solve(_T(L), np.linalg.solve(L, _T(Pxy))))
        nu = meas.residual(z, ybar)
        self.x = self.x + (K @ nu[..., None])[..., 0]
        self.P = symmetrize(self.P - K @ S @ _T(K))
        w = np.linalg.solve(L, nu[..., None])[..., 0]
        return Innovation(nu=nu, S=S, K=K, nis=np.sum(w * w, axis=-1))


def sigma_moments(rule: SigmaPointRule, motion: MotionModel, meas: MeasurementModel,
                  m: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sigma-point moments of y = h(x) for x ~ N(m, P) (SEEDS 1.3): X_i = points(m, chol P),
    ybar = weighted_mean(h(X_i)), Pxy = sum Wc (X_i - m)(Y_i - ybar)',
    Pyy = sum Wc (Y_i - ybar)(Y_i - ybar)' (residuals wrapped for angles)."""
    X = rule.points(m, cholesky(P, "covariance of the sigma points"))
    ybar, dY = weighted_mean(meas.h(X), rule.Wm, meas.h(m), meas.residual)
    dX = motion.residual(X, m[..., None, :])
    return ybar, (_T(dX) * rule.Wc) @ dY, (_T(dY) * rule.Wc) @ dY


def statistical_linear_regression(rule: SigmaPointRule, motion: MotionModel,
                                  meas: MeasurementModel, m: np.ndarray, P: np.ndarray
                                  ) -> Linearisation:
    """Statistical linear regression of h with respect to N(m, P) (Garcia-Fernandez et al. 2015):

        A = Pxy' P^-1,   h(x) ~ ybar + A (x - m),   Omega = Pyy - A P A'

    with the sigma-point moments (sigma_moments). Omega, the covariance of the linearisation
    error, is positive semidefinite for a rule with non-negative weights; a negative centre
    weight (the unscented rule with kappa < 0) can make it indefinite, and then its negative
    eigenvalues are set to zero."""
    ybar, Pxy, Pyy = sigma_moments(rule, motion, meas, m, P)
    A = _T(np.linalg.solve(P, Pxy))
    Omega = symmetrize(Pyy - A @ P @ _T(A))
    d, U = np.linalg.eigh(Omega)
    negative = d.min(axis=-1) < 0.0
    if negative.any():
        clipped = (U * np.maximum(d, 0.0)[..., None, :]) @ _T(U)
        Omega = np.where(negative[..., None, None], clipped, Omega)
    return A, ybar, Omega


class IteratedPosteriorLinearisationFilter(SigmaPointKalmanFilter):
    """Iterated posterior linearisation filter, IPLF (Garcia-Fernandez, Svensson, Morelande
    & Sarkka 2015, "Posterior linearization filter: principles and implementation using
    sigma points", IEEE Trans. Signal Processing 63(20)), damped.

    Prediction: the sigma-point prediction (the SLR of f about the posterior). Update:
    iterated.iterated_update with the statistical linear regression of h about the CURRENT
    POSTERIOR N(m_i, P_i) (statistical_linear_regression: A_i, ybar_i, Omega_i), the prior
    updated with z = A_i x + b_i + e, e ~ N(0, R + Omega_i). The first iteration, about the
    prior, is the UKF/CKF update; later ones linearise where the posterior mass is.

    Damped (the default; damped posterior linearisation, after Raitoharju, Svensson,
    Garcia-Fernandez & Piche 2018, IEEE Signal Processing Letters 25(4)): a step of the mean
    is kept only if it lowers

        V(x) = (x - x-)' P-^-1 (x - x-) + r' R~^-1 r + log det(A P- A' + R~),
        r = wrap(z - ybar),  R~ = R + Omega,  (A, ybar, Omega) the SLR of h about N(x, P_i)

    (iterated.merit: -2 log of the Laplace estimate of the posterior mass at x under the
    posterior-linearised likelihood), and is otherwise retried with Levenberg-Marquardt
    damping (iterated.damped_step). The covariance is the
    Joseph-form update of the last linearisation. `iterations` holds the count of the last
    update.

    Options: rule ("cubature", the default, or "unscented" with alpha, beta, kappa),
    max_iterations (default 30), tolerance (default 1e-4 posterior standard deviations),
    damped (default true; false: the undamped IPLF).
    """

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, rule: SigmaPointRule, max_iterations: int = MAX_ITERATIONS,
                 tolerance: float = TOLERANCE, damped: bool = DAMPED) -> None:
        super().__init__(motion, measurement, x0, P0, rule, "iplf")
        self.max_iterations, self.tolerance, self.damped = iteration_options(
            max_iterations, tolerance, damped)
        self.iterations: int | np.ndarray = 0

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        def linearise(m: np.ndarray, P: np.ndarray) -> Linearisation:
            return statistical_linear_regression(self.rule, self.motion, meas, m, P)

        self.x, self.P, info, self.iterations = iterated_update(
            self.motion, meas, self.x, self.P, z, meas.R, linearise, self.max_iterations,
            self.tolerance, self.damped)
        return info


@dataclass
class _Root:
    """Matrix 'square root' of order p: Cholesky for p = 2, principal cube root for p = 3;
    over a stack, each matrix on its own."""

    p: int

    def of(self, M: np.ndarray, what: str) -> np.ndarray:
        try:
            return cholesky(M, what) if self.p == 2 else spd_root(M, 1.0 / self.p)
        except NotPositiveDefiniteError:
            if np.ndim(M) > 2:              # the stack's matrices one by one
                return np.stack([self.of(Mi, what) for Mi in M])
        # a PSD (singular) Q or R: any factor works for tria, the principal root for p = 3
        d, U = np.linalg.eigh(symmetrize(M))
        if self.p == 2:
            return U * np.sqrt(np.clip(d, 0.0, None))
        return (U * np.clip(d, 0.0, None) ** (1.0 / self.p)) @ U.T

    def weight(self, w: float) -> float:
        return float(w) ** (1.0 / self.p)


class SquareRootUKF(GaussianFilter):
    """Square-root UKF (van der Merwe & Wan 2001; SEEDS 1.5): the factor S (P = S S') is
    propagated by QR ('tria') and rank-1 Cholesky up/down-dates.

    root=3 gives seed 002's "cubic root UKF" (SEEDS 4.5): cube roots replace the square roots
    of P0, Q, R, the spread and the QR weights. That variant is the PAPER'S EXPERIMENTAL
    VARIANT and is mathematically unsound (its factors are mutually inconsistent); it is here
    to reproduce the paper, not as an improved filter.

    A downdate that fails (very negative Wc0) falls back to the full-covariance step for that
    factor and is counted in `fallbacks`. If even that matrix is not positive definite, the
    filter raises NotPositiveDefiniteError, unless `repair` is set: then the matrix is
    repaired by clipping its eigenvalues at 1e-10 x the largest (SEEDS 1.3) and the event is
    counted in `repairs` (seed 002's cube-root variant needs it to run at all). For a stack
    of runs both counters are per run, and so are the fallbacks and repairs.
    """

    repair = False

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, rule: SigmaPointRule, root: int = 2, kind: str = "srukf") -> None:
        if not rule.center:
            raise ValueError("the square-root UKF needs an unscented rule")
        self.rule = rule
        self.root = _Root(root)
        self.kind = kind
        runs = np.shape(x0)[:-1]
        self.fallbacks: int | np.ndarray = np.zeros(runs, dtype=int) if runs else 0
        self.repairs: int | np.ndarray = np.zeros(runs, dtype=int) if runs else 0
        super().__init__(motion, measurement, x0, P0)  # sets S through the P setter

    @property
    def P(self) -> np.ndarray:  # type: ignore[override]
        return self.S @ _T(self.S)

    @P.setter
    def P(self, value: np.ndarray) -> None:
        self.S = self.root.of(value, "covariance")

    def _points(self, x: np.ndarray) -> np.ndarray:
        return self.rule.points(x, self.S, spread=self.rule.c ** (1.0 / self.root.p))

    def _factor(self, dev: np.ndarray, noise_root: np.ndarray) -> np.ndarray:
        """tria([w1 * dev_1..2n, noise root]) then the rank-1 term of the centre point (Wc0)."""
        Wc = self.rule.Wc
        noise = np.broadcast_to(noise_root, dev.shape[:-2] + np.shape(noise_root))
        S = tria(np.concatenate([self.root.weight(Wc[1]) * _T(dev[..., 1:, :]), noise], axis=-1))
        if Wc[0] == 0.0:
            return S
        v = np.sqrt(abs(Wc[0])) * dev[..., 0, :]
        updated, ok = cholupdate_each(S, v, np.sign(Wc[0]))
        return self._where_failed(updated, ok, lambda: S @ _T(S) + np.sign(Wc[0])
                                  * v[..., :, None] * v[..., None, :],
                                  "covariance after the Wc0 downdate")

    def _where_failed(self, S: np.ndarray, ok: np.ndarray, full: Callable[[], np.ndarray],
                      what: str) -> np.ndarray:
        """S, with the factors whose up/downdate failed replaced by the factor of the full
        covariance `full()` (the fallback, counted per run)."""
        if np.all(ok):
            return S
        M = full()
        if np.ndim(ok) == 0:
            self.fallbacks += 1
            L, repaired = self._full_factor(M[None], what)
            self.repairs += int(repaired[0])
            return L[0]
        bad = np.flatnonzero(~ok)
        self.fallbacks[bad] += 1
        S = S.copy()
        factors, repaired = self._full_factor(M[bad], what)
        S[bad] = factors
        self.repairs[bad[repaired]] += 1
        return S

    def _full_factor(self, M: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
        """Cholesky factors of the full-covariance fallbacks M (k, n, n), each repaired (see
        class doc) where it is not positive definite; and which were repaired (k,)."""
        M = symmetrize(M)
        if not np.all(np.isfinite(M)):
            raise EstimationError(f"{what} has non-finite entries")
        L, pd = cholesky_each(M)
        if np.all(pd):
            return L, ~pd
        bad = np.flatnonzero(~pd)
        if not self.repair:
            cholesky(M[bad[0]], what)         # raises NotPositiveDefiniteError, as it says
        d, U = np.linalg.eigh(M[bad])
        floor = 1e-10 * np.maximum(d.max(axis=-1), np.finfo(float).tiny)
        L[bad] = tria(U * np.sqrt(np.maximum(d, floor[:, None]))[:, None, :])
        return L, ~pd

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        Xp = self.motion.f(self._points(self.x), dt, _inputs_of_points(u))
        self.x, dX = weighted_mean(Xp, self.rule.Wm, self.motion.f(self.x, dt, u),
                                   self.motion.residual)
        self.S = self._factor(dX, self.root.of(self.motion.Q(dt), "process noise Q"))

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        X = self._points(self.x)
        ybar, dY = weighted_mean(meas.h(X), self.rule.Wm, meas.h(self.x), meas.residual)
        Sy = self._factor(dY, self.root.of(meas.R, "measurement noise R"))
        dX = self.motion.residual(X, self.x[..., None, :])
        Pxy = (_T(dX) * self.rule.Wc) @ dY
        # K = Pxy (Sy Sy')^-1 by two triangular solves (SEEDS 1.5).
        K = _T(np.linalg.solve(_T(Sy), np.linalg.solve(Sy, _T(Pxy))))
        nu = meas.residual(z, ybar)
        self.x = self.x + (K @ nu[..., None])[..., 0]
        U = K @ Sy
        S, ok = self.S, np.ones(self.x.shape[:-1], dtype=bool)
        for j in range(U.shape[-1]):
            S, ok_j = cholupdate_each(S, U[..., :, j], -1.0)
            ok &= ok_j
        prior = self.S
        self.S = self._where_failed(S, ok, lambda: prior @ _T(prior) - U @ _T(U),
                                    "updated covariance")
        w = np.linalg.solve(Sy, nu[..., None])[..., 0]
        return Innovation(nu=nu, S=Sy @ _T(Sy), K=K, nis=np.sum(w * w, axis=-1))
