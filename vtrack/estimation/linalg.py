"""Numerical building blocks: angle wrapping, safe Cholesky, QR 'tria', rank-1 up/down-dates."""

from __future__ import annotations

import numpy as np
from numpy.linalg import _umath_linalg


class EstimationError(ValueError):
    """A filter met something it cannot process (non-finite input, non-PD covariance)."""


class NotPositiveDefiniteError(EstimationError):
    """A covariance that must be positive definite is not."""


class DowndateError(EstimationError):
    """A Cholesky rank-1 downdate would make the factor indefinite (SEEDS 1.5)."""


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angles to (-pi, pi]: wrap(a) = pi - ((pi - a) mod 2 pi)  (SEEDS notation).

    In floating point `(pi - a) mod 2 pi` rounds up to exactly 2 pi for a just above pi
    (e.g. nextafter(pi, 4)), which would give -pi; that one value is mapped back to pi
    (exact: -pi + 2 pi == pi in binary64), so the result is always in (-pi, pi].
    """
    w = np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2.0 * np.pi)
    return w + np.where(w == -np.pi, 2.0 * np.pi, 0.0)


def symmetrize(P: np.ndarray) -> np.ndarray:
    """P <- (P + P^T) / 2 over the last two axes (works on stacks of matrices)."""
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def cholesky(P: np.ndarray, what: str = "covariance") -> np.ndarray:
    """Lower Cholesky factor of a (stack of) SPD matrix; a clear error if it is not SPD (any
    matrix of the stack)."""
    if not np.all(np.isfinite(P)):
        raise EstimationError(f"{what} has non-finite entries")
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        eig = np.linalg.eigvalsh(symmetrize(P))
        raise NotPositiveDefiniteError(
            f"{what} is not positive definite (smallest eigenvalue {eig.min():.3g})"
        ) from None


def cholesky_each(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower Cholesky factors of a stack of finite symmetric matrices (..., n, n) and, per
    matrix, whether it is positive definite (where not, its factor is NaN). The same LAPACK
    factorisation as np.linalg.cholesky, which wraps this gufunc with one error for the
    whole stack."""
    with np.errstate(invalid="ignore"):
        L = _umath_linalg.cholesky_lo(np.asarray(P, dtype=float), signature="d->d")
    return L, ~np.isnan(L[..., 0, 0])


def require_finite(a: np.ndarray, what: str) -> np.ndarray:
    """Return `a` as float array, raising EstimationError if any entry is NaN or inf."""
    a = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(a)):
        raise EstimationError(f"{what} has non-finite entries")
    return a


def tria(M: np.ndarray) -> np.ndarray:
    """Lower-triangular S with S S^T = M M^T, from the QR of M^T, diag(S) >= 0 (SEEDS 1.5);
    over stacks M (..., n, k)."""
    r = np.linalg.qr(np.swapaxes(M, -1, -2), mode="r")
    S = np.swapaxes(r, -1, -2)[..., :, : M.shape[-2]]
    signs = np.where(np.diagonal(S, axis1=-2, axis2=-1) < 0, -1.0, 1.0)
    return S * signs[..., None, :]


def cholupdate(L: np.ndarray, v: np.ndarray, sign: float = 1.0) -> np.ndarray:
    """Rank-1 update (sign=+1) or downdate (sign=-1) of a lower Cholesky factor.

    Returns L' with L' L'^T = L L^T + sign * v v^T (SEEDS 1.5). A downdate that would lose
    positive definiteness (of any factor of a stack) raises DowndateError."""
    out, ok = cholupdate_each(L, v, sign)
    if not np.all(ok):
        raise DowndateError("Cholesky downdate lost positive definiteness")
    return out


def cholupdate_each(L: np.ndarray, v: np.ndarray, sign: float = 1.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """cholupdate over a stack of factors L (..., n, n) and vectors v (..., n): the updated
    factors and, per factor, whether its update kept it positive definite (where not, its
    factor is meaningless)."""
    L = np.array(L, dtype=float, copy=True)
    v = np.array(v, dtype=float, copy=True)
    n = L.shape[-1]
    ok = np.ones(L.shape[:-2], dtype=bool)
    with np.errstate(all="ignore"):         # a failed factor carries on as garbage
        for k in range(n):
            r2 = L[..., k, k] ** 2 + sign * v[..., k] ** 2
            ok &= (r2 > 0.0) & np.isfinite(r2)
            r = np.sqrt(r2)
            c = r / L[..., k, k]
            s = v[..., k] / L[..., k, k]
            L[..., k, k] = r
            if k + 1 < n:
                L[..., k + 1:, k] = (L[..., k + 1:, k] + sign * s[..., None] * v[..., k + 1:]) \
                    / c[..., None]
                v[..., k + 1:] = c[..., None] * v[..., k + 1:] - s[..., None] * L[..., k + 1:, k]
    return L, ok


def spd_root(P: np.ndarray, power: float) -> np.ndarray:
    """Principal power P^power = U diag(d^power) U^T of an SPD matrix (seed 002's cube root);
    over a stack, NotPositiveDefiniteError if any matrix is not SPD."""
    d, U = np.linalg.eigh(symmetrize(P))
    if d.min() <= 0:
        raise NotPositiveDefiniteError("matrix root of a matrix that is not positive definite")
    return (U * (d**power)[..., None, :]) @ np.swapaxes(U, -1, -2)
