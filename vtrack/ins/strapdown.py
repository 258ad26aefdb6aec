"""Strapdown inertial navigation (seed 001 section 4; SEEDS 3.2): the mechanisation (eq. 27,
corrected), attitude from accelerometer + magnetometer (eqs. 36-37, standard form), and the
linear error model of the error-state Kalman filter (eqs. 28-35).

Frames: ENU navigation frame, FLU body frame, R = R_b^n (see vtrack.ins.so3).
Error state (estimate minus truth for navigation, residual sensor error for biases):

    dx = [dr (3), dv (3), eps (3) | dba (3), dbg (3) | dbm (3)]

9 states = the paper's; 15 = + accelerometer and gyro biases; 18 = + magnetometer bias
(body frame, uT; it only matters when the magnetometer aids the filter).  The attitude
error has the paper's sign (Titterton & Weston's psi-angle form, which is what the signs of
A and B in eqs. 28-30 imply):  R~ = (I - [eps x]) R,  so the truth is R = exp([eps x]) R~.
dba = b_a - b^_a, dbg = b_g - b^_g, dbm = b_m - b^_m: what the bias-corrected sensor still
gets wrong.  Every function takes leading batch axes (Monte Carlo runs).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from vtrack.ins.so3 import dcm_to_euler, euler_rate_matrix, exp_so3, log_so3, skew

G0 = 9.80665
GRAVITY_N = np.array([0.0, 0.0, -G0])       # g^n of eq. 27 (ENU, z up)


@dataclass
class NavState:
    """The INS solution: p (..., 3), v (..., 3), R (..., 3, 3) and the sensor-bias estimates
    (accelerometer, gyro, magnetometer; zero when the filter has no such states)."""

    p: np.ndarray
    v: np.ndarray
    R: np.ndarray
    ba: np.ndarray
    bg: np.ndarray
    bm: np.ndarray

    def copy(self) -> NavState:
        return NavState(self.p.copy(), self.v.copy(), self.R.copy(), self.ba.copy(),
                        self.bg.copy(), self.bm.copy())


# ---------------------------------------------------------------------------- mechanisation

def mechanize(p: np.ndarray, v: np.ndarray, R: np.ndarray, s_b: np.ndarray, w_ib: np.ndarray,
              dt: float, omega_ie: np.ndarray, trapezoid: bool = True
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of the strapdown equations, seed eq. 27 with gravity and Coriolis multiplied
    by dT (SEEDS 3.2 correction), flat local-level frame (omega_in = omega_ie):

        v_k = v_{k-1} + dT (R_{k-1} s_{k-1} + g^n - 2 omega_ie^n x v_{k-1})
        p_k = p_{k-1} + dT v_{k-1}              (paper, trapezoid=False)
            = p_{k-1} + dT (v_{k-1} + v_k) / 2  (trapezoid=True, second order)
        R_k = R_{k-1} expm((Omega_ib^b - Omega_in^b) dT),  omega_in^b = R_{k-1}' omega_ie^n

    s_b, w_ib are the (bias-corrected) accelerometer and gyro samples at t_{k-1}."""
    s_n = (R @ s_b[..., None])[..., 0]
    v_new = v + dt * (s_n + GRAVITY_N - v @ _coriolis(_key(omega_ie)))  # 2 omega_ie x v
    p_new = p + dt * (0.5 * (v + v_new) if trapezoid else v)
    w_in_b = omega_ie @ R                                                  # R' omega_ie
    R_new = R @ exp_so3((w_ib - w_in_b) * dt)
    return p_new, v_new, R_new


# ------------------------------------------------------- attitude from accelerometer + mag

def tilt_from_accel(s_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch from the specific force of a non-accelerating vehicle (SEEDS 3.2, the
    standard form of eq. 36; FLU body, at rest s^b = g [-sin(th), sin(ph) cos(th),
    cos(ph) cos(th)]):  roll = atan2(s_y, s_z),  pitch = atan2(-s_x, sqrt(s_y^2 + s_z^2))."""
    sx, sy, sz = s_b[..., 0], s_b[..., 1], s_b[..., 2]
    return np.arctan2(sy, sz), np.arctan2(-sx, np.hypot(sy, sz))


def heading_from_mag(m_b: np.ndarray, roll: np.ndarray, pitch: np.ndarray,
                     declination: float = 0.0) -> np.ndarray:
    """Tilt-compensated heading (standard form of eq. 37, SEEDS 3.2):

        X_h = m_x cos(th) + m_y sin(th) sin(ph) + m_z sin(th) cos(ph)
        Y_h = m_y cos(ph) - m_z sin(ph)

    (X_h, Y_h) = Rz(yaw)' m^n: the body field levelled.  In the FLU/ENU convention the yaw
    (counter-clockwise from East) is  atan2(X_h, Y_h) - D; the compass heading clockwise
    from North is atan2(Y_h, X_h) + D, i.e. the textbook NED/FRD atan2(-Y_h, X_h) + D with
    the body y axis flipped."""
    mx, my, mz = m_b[..., 0], m_b[..., 1], m_b[..., 2]
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    xh = mx * cp + my * sp * sr + mz * sp * cr
    yh = my * cr - mz * sr
    return wrap(np.arctan2(xh, yh) - declination)


def attitude_from_accel_mag(s_b: np.ndarray, m_b: np.ndarray, declination: float = 0.0
                            ) -> np.ndarray:
    """g_MEAS of eq. 36-37 (standard form): [roll, pitch, yaw] from one accelerometer and one
    magnetometer sample, valid when the vehicle does not accelerate."""
    roll, pitch = tilt_from_accel(s_b)
    return np.stack([roll, pitch, heading_from_mag(m_b, roll, pitch, declination)], axis=-1)


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles to (-pi, pi] (SEEDS notation)."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


# -------------------------------------------------------------------------- error model

def error_dynamics(R: np.ndarray, s_n: np.ndarray, omega_ie: np.ndarray, n_states: int,
                   coriolis: bool = True) -> np.ndarray:
    """A of eqs. 28-30, local-level simplification of SEEDS 3.2 (A_pv = I, A_pp = A_vp =
    A_ep = A_ev = 0, A_vv = -2 (omega_ie x), omega_in = omega_ie):

        d(dr)/dt  = dv
        d(dv)/dt  = A_vv dv + (s^n x) eps + R_b^n dba
        d(eps)/dt = -(omega_in^n x) eps - R_b^n dbg
        d(dba)/dt = w_ba,   d(dbg)/dt = w_bg,   d(dbm)/dt = w_bm    (random walks)

    For n_states = 9 the bias columns are dropped (the paper's model, eq. 30: the sensor
    errors u = [ds, dw] enter only as noise through B); 18 adds the magnetometer bias."""
    return _error_matrix(_steady_dynamics(_key(omega_ie), n_states, coriolis), R, s_n, 1.0)


def transition(A: np.ndarray, dt: float) -> np.ndarray:
    """Phi = I + A dT  (eq. 32)."""
    return np.eye(A.shape[-1]) + A * dt


def error_transition(R: np.ndarray, s_n: np.ndarray, omega_ie: np.ndarray, n_states: int,
                     dt: float, coriolis: bool = True) -> np.ndarray:
    """transition(error_dynamics(...), dt), the same numbers, with I + A dT of the blocks
    that do not change with the epoch computed once (the filter's step)."""
    steady = _steady_transition(_key(omega_ie), n_states, coriolis, dt)
    return _error_matrix(steady, R, s_n, dt)


def _key(omega_ie: np.ndarray) -> tuple[float, ...]:
    return tuple(float(w) for w in omega_ie)


@lru_cache(maxsize=16)
def _coriolis(omega_ie: tuple[float, ...]) -> np.ndarray:
    """(2 omega_ie x)' for v @ it = 2 omega_ie x v (the mechanisation's Coriolis term)."""
    out = (2.0 * skew(omega_ie)).T
    out.flags.writeable = False
    return out


def _error_matrix(steady: np.ndarray, R: np.ndarray, s_n: np.ndarray, scale: float
                  ) -> np.ndarray:
    """`steady` with the blocks of A that change with the attitude and the specific force,
    times `scale`, written in (one per batch element)."""
    n = steady.shape[-1]
    out = np.empty(R.shape[:-2] + (n, n))
    out[...] = steady
    out[..., 3:6, 6:9] = skew(s_n) * scale
    if n >= 15:
        out[..., 3:6, 9:12] = R * scale
        out[..., 6:9, 12:15] = -R * scale
    return out


@lru_cache(maxsize=16)
def _steady_dynamics(omega_ie: tuple[float, ...], n_states: int, coriolis: bool
                     ) -> np.ndarray:
    """The blocks of A that do not change with the attitude or the specific force."""
    if n_states not in (9, 15, 18):
        raise ValueError("n_states must be 9, 15 or 18")
    A = np.zeros((n_states, n_states))
    A[0:3, 3:6] = np.eye(3)
    if coriolis:
        A[3:6, 3:6] = -2.0 * skew(omega_ie)
    A[6:9, 6:9] = -skew(omega_ie)
    A.flags.writeable = False
    return A


@lru_cache(maxsize=16)
def _steady_transition(omega_ie: tuple[float, ...], n_states: int, coriolis: bool, dt: float
                       ) -> np.ndarray:
    F = transition(_steady_dynamics(omega_ie, n_states, coriolis), dt)
    F.flags.writeable = False
    return F


def process_noise(R: np.ndarray, n_states: int, dt: float, accel_psd: float, gyro_psd: float,
                  accel_bias_rw_psd: float = 0.0, gyro_bias_rw_psd: float = 0.0,
                  mag_bias_rw_psd: float = 0.0) -> np.ndarray:
    """Q_k = B diag(q_a I3, q_g I3 [, q_ba I3, q_bg I3 [, q_bm I3]]) B' dT  (eq. 33, SEEDS 3.2
    [A]) with B = [[0, 0], [R, 0], [0, -R]] (eq. 30) extended by identity blocks for the bias
    walks; q are power spectral densities (squared noise densities).  With isotropic q the
    result does not depend on R (R R' = I)."""
    batch = R.shape[:-2]
    Q = np.zeros(batch + (n_states, n_states))
    RRt = R @ np.swapaxes(R, -1, -2)
    Q[..., 3:6, 3:6] = accel_psd * RRt * dt
    Q[..., 6:9, 6:9] = gyro_psd * RRt * dt
    if n_states >= 15:
        Q[..., 9:12, 9:12] = accel_bias_rw_psd * dt * np.eye(3)
        Q[..., 12:15, 12:15] = gyro_bias_rw_psd * dt * np.eye(3)
    if n_states == 18:
        Q[..., 15:18, 15:18] = mag_bias_rw_psd * dt * np.eye(3)
    return Q


def attitude_jacobian(R_ins: np.ndarray) -> np.ndarray:
    """d(rpy~)/d(eps) = -M(rpy~)^-1: how the INS Euler angles move with the attitude error
    (R~ = exp(-[eps x]) R).  Near level flight this is -I (the paper's eq. 34 H = I9 holds
    only up to this sign; SEEDS 3.2 asks to map Euler differences to eps)."""
    M = euler_rate_matrix(dcm_to_euler(R_ins))
    return -np.linalg.inv(M)


def heading_jacobian(m_b: np.ndarray, roll: np.ndarray, pitch: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Partial derivatives of heading_from_mag: d/dm (..., 3), d/droll, d/dpitch (...).
    With yaw = atan2(X_h, Y_h):  d yaw = (Y_h dX_h - X_h dY_h) / (X_h^2 + Y_h^2)."""
    mx, my, mz = m_b[..., 0], m_b[..., 1], m_b[..., 2]
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    xh = mx * cp + my * sp * sr + mz * sp * cr
    yh = my * cr - mz * sr
    n2 = xh**2 + yh**2
    dx_dm = np.stack([cp, sp * sr, sp * cr], -1)
    dy_dm = np.stack([np.zeros_like(cr), cr, -sr], -1)
    d_m = (yh[..., None] * dx_dm - xh[..., None] * dy_dm) / n2[..., None]
    d_roll = (yh * (my * sp * cr - mz * sp * sr) - xh * (-my * sr - mz * cr)) / n2
    d_pitch = yh * (-mx * sp + my * cp * sr + mz * cp * cr) / n2
    return d_m, d_roll, d_pitch


def tilt_jacobian(s_b: np.ndarray) -> np.ndarray:
    """d[roll, pitch]/d s of tilt_from_accel (..., 2, 3): how an accelerometer bias leaks
    into the accelerometer roll and pitch."""
    sx, sy, sz = s_b[..., 0], s_b[..., 1], s_b[..., 2]
    r2 = sy**2 + sz**2
    r = np.sqrt(r2)
    n2 = sx**2 + r2
    zero = np.zeros_like(sx)
    d_roll = np.stack([zero, sz / r2, -sy / r2], -1)
    d_pitch = np.stack([-r / n2, sx * sy / (r * n2), sx * sz / (r * n2)], -1)
    return np.stack([d_roll, d_pitch], axis=-2)


def correct(nav: NavState, dx: np.ndarray) -> NavState:
    """Closed-loop feedback (SEEDS 3.2): p <- p~ - dr, v <- v~ - dv, R <- exp([eps x]) R~,
    b^ <- b^ + db; the caller then resets dx to 0."""
    n = dx.shape[-1]
    R = exp_so3(dx[..., 6:9]) @ nav.R
    return NavState(nav.p - dx[..., 0:3], nav.v - dx[..., 3:6], R,
                    nav.ba + dx[..., 9:12] if n >= 15 else nav.ba,
                    nav.bg + dx[..., 12:15] if n >= 15 else nav.bg,
                    nav.bm + dx[..., 15:18] if n >= 18 else nav.bm)


def attitude_error(R_est: np.ndarray, R_true: np.ndarray) -> np.ndarray:
    """eps with R_est = exp(-[eps x]) R_true, i.e. eps = log(R_true R_est')  (the paper's
    sign; used for NEES and the attitude RMSE)."""
    return log_so3(R_true @ np.swapaxes(R_est, -1, -2))
