"""Filter kinds by name: the one registry (FILTER_KINDS, `register`, `make_filter`).

The core's kinds are registered here: kf, ekf, iekf, ukf, ckf, iplf, srukf, crukf. Packages on
top of the core add theirs by calling `register` when imported (vtrack.adaptive: ankf1, ankf2,
fuzzy-r, fuzzy-q, siim-ekf); vtrack.filter_kinds imports them all. Nothing in
vtrack.estimation imports those packages, so the core has no import circle.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vtrack.estimation.filters import (
    ExtendedKalmanFilter,
    GaussianFilter,
    IteratedExtendedKalmanFilter,
)
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.sigma_filters import (
    IteratedPosteriorLinearisationFilter,
    SigmaPointKalmanFilter,
    SquareRootUKF,
)
from vtrack.estimation.sigma_points import SigmaPointRule, cubature, unscented

FilterFactory = Callable[..., GaussianFilter]
FILTER_KINDS: dict[str, tuple[FilterFactory, tuple[str, ...]]] = {}


def register(kind: str, options: tuple[str, ...] = ()) -> Callable[[FilterFactory], FilterFactory]:
    """Register a filter factory f(motion, measurement, x0, P0, **options) under `kind`."""

    def deco(factory: FilterFactory) -> FilterFactory:
        FILTER_KINDS[kind] = (factory, options)
        return factory

    return deco


def make_filter(kind: str, motion: MotionModel, measurement: MeasurementModel,
                x0: np.ndarray, P0: np.ndarray, **options: object) -> GaussianFilter:
    """Build a filter by kind name; unknown kinds and options raise ValueError."""
    if kind not in FILTER_KINDS:
        raise ValueError(f"unknown filter kind {kind!r} (known: {', '.join(sorted(FILTER_KINDS))})")
    factory, allowed = FILTER_KINDS[kind]
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ValueError(f"filter kind {kind!r} does not take option(s) {', '.join(unknown)}"
                         + (f" (it takes: {', '.join(allowed)})" if allowed else ""))
    return factory(motion, measurement, x0, P0, **options)


_UT = ("alpha", "beta", "kappa")
_ITERATION = ("max_iterations", "tolerance", "damped")


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


@register("iekf", _ITERATION)
def _iekf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
          **iteration: float) -> GaussianFilter:
    return IteratedExtendedKalmanFilter(motion, meas, x0, P0, **iteration)


@register("ukf", _UT)
def _ukf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
         **ut: float) -> GaussianFilter:
    return SigmaPointKalmanFilter(motion, meas, x0, P0, unscented(motion.n, **ut), "ukf")


@register("ckf")
def _ckf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray
         ) -> GaussianFilter:
    return SigmaPointKalmanFilter(motion, meas, x0, P0, cubature(motion.n), "ckf")


def _iplf_rule(n: int, rule: object, ut: dict[str, float]) -> SigmaPointRule:
    if rule == "cubature":
        if ut:
            raise ValueError(f"options {', '.join(sorted(ut))} need rule = \"unscented\"")
        return cubature(n)
    if rule == "unscented":
        return unscented(n, **ut)
    raise ValueError(f"option rule must be \"cubature\" or \"unscented\" (got {rule!r})")


@register("iplf", ("rule",) + _UT + _ITERATION)
def _iplf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
          rule: str = "cubature", **options: float) -> GaussianFilter:
    ut = {k: options.pop(k) for k in _UT if k in options}
    return IteratedPosteriorLinearisationFilter(motion, meas, x0, P0,
                                                _iplf_rule(motion.n, rule, ut), **options)


@register("srukf", _UT)
def _srukf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
           **ut: float) -> GaussianFilter:
    return SquareRootUKF(motion, meas, x0, P0, unscented(motion.n, **ut), 2, "srukf")


@register("crukf", _UT)
def _crukf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
           **ut: float) -> GaussianFilter:
    return SquareRootUKF(motion, meas, x0, P0, unscented(motion.n, **ut), 3, "crukf")
