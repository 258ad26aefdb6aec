"""Kalman filter steps (SEEDS 1.1, 1.2), written once for one target or a stack of N targets.

Every array may carry leading batch axes: x (..., n), P (..., n, n), z (..., m),
H (..., m, n), R (..., m, m). The tracker steps all vehicles' filters with one call; the
seed experiments step all Monte Carlo runs of a case with one call (the filters of
vtrack.estimation.filters holding a stack of runs), and `vtrack filter` one track.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from vtrack.estimation.linalg import NotPositiveDefiniteError, cholesky, symmetrize

_T = lambda a: np.swapaxes(a, -1, -2)  # noqa: E731  (transpose of the last two axes)


@lru_cache(maxsize=32)
def _eye(n: int) -> np.ndarray:
    eye = np.eye(n)
    eye.flags.writeable = False
    return eye


@dataclass
class Innovation:
    """What an update saw: innovation nu = z - h(x-), its covariance S, gain K, NIS nu' S^-1 nu."""

    nu: np.ndarray
    S: np.ndarray
    K: np.ndarray
    nis: np.ndarray


def kf_predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray,
               fx: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Predict: x- = F x (or the given fx = f(x)),  P- = F P F' + Q  (SEEDS 1.1; seed 001 eq. 23,
    with Q added once)."""
    x_pred = (F @ x[..., None])[..., 0] if fx is None else fx
    return x_pred, symmetrize(F @ P @ _T(F) + Q)


def kf_update(x: np.ndarray, P: np.ndarray, nu: np.ndarray, H: np.ndarray, R: np.ndarray,
              mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, Innovation]:
    """Update with innovation nu (= z - h(x-), already wrapped for angles), Joseph form:

        S = H P H' + R,  K = P H' S^-1,  x = x- + K nu,
        P = (I - K H) P (I - K H)' + K R K',  P <- (P + P')/2      (SEEDS 1.1)

    `mask` (..., m) marks the rows present; a missing row gets a zero H row, zero innovation
    and a decoupled unit variance, so it changes nothing (this is exact, and lets a batch of
    targets with different missing rows share one call). S is checked by a Cholesky
    factorisation (NotPositiveDefiniteError if it fails); for the small S here one batched
    inverse serves the gain and the NIS.
    """
    H = np.ascontiguousarray(H)  # matmul on a zero-stride broadcast view is ~4x slower
    if mask is not None and not mask.all():
        keep = mask.astype(float)
        nu = np.where(mask, nu, 0.0)
        H = H * keep[..., :, None]
        outer = keep[..., :, None] * keep[..., None, :]
        R = R * outer + _eye(R.shape[-1]) * (1.0 - keep[..., :, None])
    PHt = P @ _T(H)
    S = symmetrize(H @ PHt + R)
    try:
        np.linalg.cholesky(S)  # the positive-definiteness check
    except np.linalg.LinAlgError:
        raise NotPositiveDefiniteError("innovation covariance S is not positive definite") from None
    # One solve with S for the gain and the NIS together: S^-1 [H P | nu] (no explicit inverse).
    sol = np.linalg.solve(S, np.concatenate([_T(PHt), nu[..., :, None]], axis=-1))
    Kt = np.ascontiguousarray(sol[..., :-1])
    K = _T(Kt)
    x_new = x + (K @ nu[..., None])[..., 0]
    A = _eye(P.shape[-1]) - K @ H
    P_new = symmetrize(A @ P @ _T(A) + K @ R @ Kt)
    nis = np.sum(nu * sol[..., -1], axis=-1)
    return x_new, P_new, Innovation(nu=nu, S=S, K=K, nis=nis)


def smooth_gap(x: np.ndarray, P: np.ndarray, Phi: np.ndarray, x_prior: np.ndarray,
               P_prior: np.ndarray, x_post: np.ndarray) -> np.ndarray:
    """Fixed-interval (Rauch-Tung-Striebel) smoothed means over a gap of predictions.

    x (m, n), P (m, n, n): the means and covariances predicted at t_1..t_m after the last
    update, with no measurement until t_n > t_m, where the update took the prior (x_prior,
    P_prior) to the mean x_post; Phi (m, n, n) the transitions t_j -> t_n. With only
    predictions in between (x_j+1 = F_j x_j), the RTS gains C_j = P_j F_j' P_j+1^-1 chain to
    C_j ... C_n-1 = P_j Phi_j' P_prior^-1, the smoother's correction at t_n carried back by
    each state's covariance with x_n:  x_s(j) = x_j + P_j Phi_j' P_prior^-1 (x_post - x_prior).
    """
    L = cholesky(P_prior, "prior covariance of the update that ends the gap")
    y = np.linalg.solve(_T(L), np.linalg.solve(L, x_post - x_prior))
    return x + (P @ _T(Phi) @ y)
