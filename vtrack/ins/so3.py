"""Rotation helpers for strapdown navigation (seed 001 section 4): skew matrices, the SO(3)
exponential and logarithm (Rodrigues), and ZYX Euler angles.

Conventions (used by vtrack.ins.strapdown and vtrack.sim.ins_trajectory):
* navigation frame n = local-level East-North-Up (g^n = [0, 0, -9.80665], seed eq. 27);
* body frame b = Forward-Left-Up;
* R = R_b^n = Rz(yaw) Ry(pitch) Rx(roll) maps body vectors to n.  Yaw is counter-clockwise
  from East; with FLU a positive pitch is nose DOWN and a positive roll is right wing down.
Every function accepts leading batch axes.
"""

from __future__ import annotations

import numpy as np

_SMALL = 1e-8
_EYE3 = np.eye(3)
_EYE3.flags.writeable = False


def skew(w: np.ndarray) -> np.ndarray:
    """(w x): the matrix with skew(w) @ u = cross(w, u)  (the Omega matrices of eq. 27)."""
    w = np.asarray(w, dtype=float)
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def vee(S: np.ndarray) -> np.ndarray:
    """Inverse of skew for the antisymmetric part: vee(skew(w)) = w."""
    return 0.5 * np.stack([S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0],
                           S[..., 1, 0] - S[..., 0, 1]], axis=-1)


def exp_so3(phi: np.ndarray) -> np.ndarray:
    """expm(skew(phi)) by Rodrigues: I + sin(a)/a K + (1 - cos a)/a^2 K^2, a = |phi|,
    K^2 = phi phi' - a^2 I (the attitude update of eq. 27, phi = (omega_ib - omega_in) dT)."""
    phi = np.asarray(phi, dtype=float)
    a2 = np.einsum("...i,...i->...", phi, phi)
    small = a2 < 1e-8
    a2s = np.where(small, 1.0, a2)
    a = np.sqrt(a2s)
    # Taylor series below 1e-4 rad keeps full double precision.
    s = np.where(small, 1.0 - a2 / 6.0, np.sin(a) / a)[..., None, None]
    c = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(a)) / a2s)[..., None, None]
    K2 = phi[..., :, None] * phi[..., None, :] - a2[..., None, None] * _EYE3
    return _EYE3 + s * skew(phi) + c * K2


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector phi with exp_so3(phi) = R, |phi| <= pi (rotation angles up to pi - 1e-6)."""
    R = np.asarray(R, dtype=float)
    cos_a = np.clip(0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    a = np.arccos(cos_a)
    v = vee(R)  # = sin(a) * axis
    small = a < 1e-4
    sin_a = np.sin(a)
    factor = np.where(small, 1.0 + a * a / 6.0, a / np.where(small, 1.0, sin_a))
    return factor[..., None] * v


def rot_x(a: np.ndarray | float) -> np.ndarray:
    """Rotation about x by angle a (batch over a)."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1),
                     np.stack([z, s, c], -1)], -2)


def rot_y(a: np.ndarray | float) -> np.ndarray:
    """Rotation about y by angle a (batch over a)."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                     np.stack([-s, z, c], -1)], -2)


def rot_z(a: np.ndarray | float) -> np.ndarray:
    """Rotation about z by angle a (batch over a)."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1),
                     np.stack([z, z, o], -1)], -2)


def euler_to_dcm(rpy: np.ndarray) -> np.ndarray:
    """R_b^n = Rz(yaw) Ry(pitch) Rx(roll) from rpy = [roll, pitch, yaw] (..., 3)."""
    rpy = np.asarray(rpy, dtype=float)
    return rot_z(rpy[..., 2]) @ rot_y(rpy[..., 1]) @ rot_x(rpy[..., 0])


def dcm_to_euler(R: np.ndarray) -> np.ndarray:
    """[roll, pitch, yaw] of R = Rz Ry Rx: roll = atan2(R21, R22), pitch = -asin(R20),
    yaw = atan2(R10, R00)  (the orientation vector g~ of eq. 35, cf. Titterton & Weston)."""
    R = np.asarray(R, dtype=float)
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    pitch = -np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def euler_rate_matrix(rpy: np.ndarray) -> np.ndarray:
    """M(rpy) with delta_n = M d(rpy): the nav-frame rotation vector of a small change of the
    Euler angles, columns = nav axes of the roll, pitch and yaw rotations:
    [Rz Ry e_x, Rz e_y, e_z].  exp(skew(M d)) R(rpy) = R(rpy + d) to first order."""
    rpy = np.asarray(rpy, dtype=float)
    th, ps = rpy[..., 1], rpy[..., 2]
    cth, sth, cps, sps = np.cos(th), np.sin(th), np.cos(ps), np.sin(ps)
    z, o = np.zeros_like(th), np.ones_like(th)
    col_roll = np.stack([cps * cth, sps * cth, -sth], -1)
    col_pitch = np.stack([-sps, cps, z], -1)
    col_yaw = np.stack([z, z, o], -1)
    return np.stack([col_roll, col_pitch, col_yaw], axis=-1)


def orthonormalize(R: np.ndarray) -> np.ndarray:
    """Nearest rotation matrix (polar factor via SVD); removes rounding drift of long runs."""
    U, _, Vt = np.linalg.svd(R)
    return U @ Vt
