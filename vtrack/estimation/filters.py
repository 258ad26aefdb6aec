"""Filters as objects with one small surface: predict(dt, u), update(z), x, P.

KF/EKF share one step (vtrack.estimation.kalman); UKF and CKF share one sigma-point step and
differ only in their SigmaPointRule; the square-root UKF and seed 002's cube-root variant share
one square-root step and differ only in the root. Missing measurement cells are NaN.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vtrack.estimation.kalman import Innovation, kf_predict, kf_update
from vtrack.estimation.linalg import (
    DowndateError,
    EstimationError,
    NotPositiveDefiniteError,
    cholesky,
    cholupdate,
    require_finite,
    spd_root,
    symmetrize,
    tria,
)
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.sigma_points import SigmaPointRule, cubature, unscented


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

    With linear models it is exactly the linear KF (kind 'kf')."""

    kind = "ekf"

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        F = self.motion.F(self.x, dt, u)
        self.x, self.P = kf_predict(self.x, self.P, F, self.motion.Q(dt),
                                    fx=self.motion.f(self.x, dt, u))

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        return self._kalman_update(meas, z, meas.R)

    def _kalman_update(self, meas: MeasurementModel, z: np.ndarray, R: np.ndarray) -> Innovation:
        nu = meas.residual(z, meas.h(self.x))
        self.x, self.P, info = kf_update(self.x, self.P, nu, meas.H(self.x), R)
        return info


def weighted_mean(Y: np.ndarray, Wm: np.ndarray, ref: np.ndarray,
                  residual: Callable[[np.ndarray, np.ndarray], np.ndarray]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Sigma-point mean taken relative to a reference, ybar = ref + sum Wm_i r(Y_i, ref), and the
    deviations r(Y_i, ybar). With wrapped residuals this averages angles across +-pi (SEEDS 1.4)."""
    mean = ref + Wm @ residual(Y, ref)
    return mean, residual(Y, mean)


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
        Xp = self.motion.f(X, dt, u)
        ref = self.motion.f(self.x, dt, u)
        self.x, dX = weighted_mean(Xp, self.rule.Wm, ref, self.motion.residual)
        self.P = symmetrize((dX.T * self.rule.Wc) @ dX + self.motion.Q(dt))

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        X = self.rule.points(self.x, cholesky(self.P, "predicted covariance"))
        ybar, dY = weighted_mean(meas.h(X), self.rule.Wm, meas.h(self.x), meas.residual)
        dX = self.motion.residual(X, self.x)
        S = symmetrize((dY.T * self.rule.Wc) @ dY + meas.R)
        Pxy = (dX.T * self.rule.Wc) @ dY
        L = cholesky(S, "innovation covariance S")
        # K = Pxy S^-1 through the factor. numpy's solve, not scipy's solve_triangular: the
        # latter can take milliseconds per tiny call under a multi-threaded OpenBLAS.
        K = np.linalg.solve(L.T, np.linalg.solve(L, Pxy.T)).T
        nu = meas.residual(z, ybar)
        self.x = self.x + K @ nu
        self.P = symmetrize(self.P - K @ S @ K.T)
        w = np.linalg.solve(L, nu)
        return Innovation(nu=nu, S=S, K=K, nis=np.asarray(w @ w))


@dataclass
class _Root:
    """Matrix 'square root' of order p: Cholesky for p = 2, principal cube root for p = 3."""

    p: int

    def of(self, M: np.ndarray, what: str) -> np.ndarray:
        if self.p == 2:
            try:
                return cholesky(M, what)
            except NotPositiveDefiniteError:  # a PSD (singular) Q: any factor works for tria
                d, U = np.linalg.eigh(symmetrize(M))
                return U * np.sqrt(np.clip(d, 0.0, None))
        try:
            return spd_root(M, 1.0 / self.p)
        except NotPositiveDefiniteError:  # a PSD (singular) Q or R, as for p = 2 above
            d, U = np.linalg.eigh(symmetrize(M))
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
    counted in `repairs` (seed 002's cube-root variant needs it to run at all).
    """

    repair = False

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, rule: SigmaPointRule, root: int = 2, kind: str = "srukf") -> None:
        if not rule.center:
            raise ValueError("the square-root UKF needs an unscented rule")
        self.rule = rule
        self.root = _Root(root)
        self.kind = kind
        self.fallbacks = 0
        self.repairs = 0
        super().__init__(motion, measurement, x0, P0)  # sets S through the P setter

    @property
    def P(self) -> np.ndarray:  # type: ignore[override]
        return self.S @ self.S.T

    @P.setter
    def P(self, value: np.ndarray) -> None:
        self.S = self.root.of(value, "covariance")

    def _points(self, x: np.ndarray) -> np.ndarray:
        return self.rule.points(x, self.S, spread=self.rule.c ** (1.0 / self.root.p))

    def _factor(self, dev: np.ndarray, noise_root: np.ndarray) -> np.ndarray:
        """tria([w1 * dev_1..2n, noise root]) then the rank-1 term of the centre point (Wc0)."""
        Wc = self.rule.Wc
        S = tria(np.hstack([self.root.weight(Wc[1]) * dev[1:].T, noise_root]))
        if Wc[0] == 0.0:
            return S
        v = np.sqrt(abs(Wc[0])) * dev[0]
        try:
            return cholupdate(S, v, np.sign(Wc[0]))
        except DowndateError:
            self.fallbacks += 1
            return self._full_factor(S @ S.T + np.sign(Wc[0]) * np.outer(v, v),
                                     "covariance after the Wc0 downdate")

    def _full_factor(self, M: np.ndarray, what: str) -> np.ndarray:
        """Cholesky factor of the full-covariance fallback, or its repair (see class doc)."""
        M = symmetrize(M)
        try:
            return cholesky(M, what)
        except NotPositiveDefiniteError:
            if not self.repair or not np.all(np.isfinite(M)):
                raise
            self.repairs += 1
            d, U = np.linalg.eigh(M)
            floor = 1e-10 * max(float(d.max()), np.finfo(float).tiny)
            return tria(U * np.sqrt(np.maximum(d, floor)))

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        Xp = self.motion.f(self._points(self.x), dt, u)
        self.x, dX = weighted_mean(Xp, self.rule.Wm, self.motion.f(self.x, dt, u),
                                   self.motion.residual)
        self.S = self._factor(dX, self.root.of(self.motion.Q(dt), "process noise Q"))

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        X = self._points(self.x)
        ybar, dY = weighted_mean(meas.h(X), self.rule.Wm, meas.h(self.x), meas.residual)
        Sy = self._factor(dY, self.root.of(meas.R, "measurement noise R"))
        dX = self.motion.residual(X, self.x)
        Pxy = (dX.T * self.rule.Wc) @ dY
        # K = Pxy (Sy Sy')^-1 by two triangular solves (SEEDS 1.5).
        K = np.linalg.solve(Sy.T, np.linalg.solve(Sy, Pxy.T)).T
        nu = meas.residual(z, ybar)
        self.x = self.x + K @ nu
        U = K @ Sy
        S = self.S
        try:
            for j in range(U.shape[1]):
                S = cholupdate(S, U[:, j], -1.0)
        except DowndateError:
            self.fallbacks += 1
            S = self._full_factor(self.S @ self.S.T - U @ U.T, "updated covariance")
        self.S = S
        w = np.linalg.solve(Sy, nu)
        return Innovation(nu=nu, S=Sy @ Sy.T, K=K, nis=np.asarray(w @ w))


# ---------------------------------------------------------------------------- registry

FilterFactory = Callable[..., GaussianFilter]
FILTER_KINDS: dict[str, tuple[FilterFactory, tuple[str, ...]]] = {}


def register(kind: str, options: tuple[str, ...] = ()) -> Callable[[FilterFactory], FilterFactory]:
    """Register a filter factory f(motion, measurement, x0, P0, **options) under `kind`."""

    def deco(factory: FilterFactory) -> FilterFactory:
        FILTER_KINDS[kind] = (factory, options)
        return factory

    return deco


def make_filter(kind: str, motion: MotionModel, measurement: MeasurementModel,
                x0: np.ndarray, P0: np.ndarray, **options: float) -> GaussianFilter:
    """Build a filter by kind name; unknown kinds and options raise ValueError."""
    import vtrack.estimation.adaptive  # noqa: F401  (registers ankf1, ankf2)
    import vtrack.estimation.fuzzy  # noqa: F401  (registers fuzzy-r, fuzzy-q, siim-ekf)

    if kind not in FILTER_KINDS:
        raise ValueError(f"unknown filter kind {kind!r} (known: {', '.join(sorted(FILTER_KINDS))})")
    factory, allowed = FILTER_KINDS[kind]
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ValueError(f"filter kind {kind!r} does not take option(s) {', '.join(unknown)}"
                         + (f" (it takes: {', '.join(allowed)})" if allowed else ""))
    return factory(motion, measurement, x0, P0, **options)


_UT = ("alpha", "beta", "kappa")


@register("kf")
def _kf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray
        ) -> GaussianFilter:
    if not (motion.linear and meas.linear):
        raise ValueError("filter kind 'kf' needs a linear motion and measurement model "
                         "(use ekf, ukf or ckf)")
    f = ExtendedKalmanFilter(motion, meas, x0, P0)
    f.kind = "kf"
    return f


@register("ekf")
def _ekf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray
         ) -> GaussianFilter:
    return ExtendedKalmanFilter(motion, meas, x0, P0)


@register("ukf", _UT)
def _ukf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
         **ut: float) -> GaussianFilter:
    return SigmaPointKalmanFilter(motion, meas, x0, P0, unscented(motion.n, **ut), "ukf")


@register("ckf")
def _ckf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray
         ) -> GaussianFilter:
    return SigmaPointKalmanFilter(motion, meas, x0, P0, cubature(motion.n), "ckf")


@register("srukf", _UT)
def _srukf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
           **ut: float) -> GaussianFilter:
    return SquareRootUKF(motion, meas, x0, P0, unscented(motion.n, **ut), 2, "srukf")


@register("crukf", _UT)
def _crukf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
           **ut: float) -> GaussianFilter:
    return SquareRootUKF(motion, meas, x0, P0, unscented(motion.n, **ut), 3, "crukf")
