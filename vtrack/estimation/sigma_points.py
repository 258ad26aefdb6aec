"""Sigma-point rules: the scaled unscented transform and the cubature rule (SEEDS 1.3).

A rule is points X_i = m + spread * (+-L_i) (plus the centre for the unscented rule) and the
weights Wm, Wc. UKF, CKF and the square-root filters differ only in the rule they use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SigmaPointRule:
    """2n (+1 centre) points m +- spread * L_i with mean weights Wm and covariance weights Wc."""

    n: int
    spread: float          # sqrt(n + lambda) for the UT, sqrt(n) for the CKF
    Wm: np.ndarray
    Wc: np.ndarray
    center: bool
    c: float               # n + lambda (the cube-root variant needs it; see sigma_filters)

    def points(self, m: np.ndarray, L: np.ndarray, spread: float | None = None) -> np.ndarray:
        """Sigma points (N, n) of mean m and factor L (L L' = P, or the factor S of SR filters);
        (..., N, n) for stacks m (..., n), L (..., n, n)."""
        s = self.spread if spread is None else spread
        cols = s * np.swapaxes(L, -1, -2)
        mean = m[..., None, :]
        pts = [mean] if self.center else []
        return np.concatenate(pts + [mean + cols, mean - cols], axis=-2)


def unscented(n: int, alpha: float = 1.0, beta: float = 0.0, kappa: float | None = None
              ) -> SigmaPointRule:
    """Scaled UT: lambda = alpha^2 (n + kappa) - n, Wm0 = lambda/c, Wc0 = Wm0 + 1 - alpha^2 + beta,
    Wi = 1/(2c), c = n + lambda  (seed 000 eq. 10; defaults alpha=1, beta=0, kappa=3-n)."""
    if kappa is None:
        kappa = 3.0 - n
    lam = alpha**2 * (n + kappa) - n
    c = n + lam
    if c <= 0:
        raise ValueError(f"unscented rule needs n + lambda > 0 (got {c:g})")
    Wm = np.full(2 * n + 1, 1.0 / (2.0 * c))
    Wc = Wm.copy()
    Wm[0] = lam / c
    Wc[0] = lam / c + (1.0 - alpha**2 + beta)
    return SigmaPointRule(n=n, spread=float(np.sqrt(c)), Wm=Wm, Wc=Wc, center=True, c=c)


def cubature(n: int) -> SigmaPointRule:
    """Third-degree spherical-radial cubature: 2n points m +- sqrt(n) L_i, weights 1/(2n)
    (seed 000 eqs. 14-24, as in Arasaratnam & Haykin 2009)."""
    W = np.full(2 * n, 1.0 / (2.0 * n))
    return SigmaPointRule(n=n, spread=float(np.sqrt(n)), Wm=W, Wc=W.copy(), center=False,
                          c=float(n))
