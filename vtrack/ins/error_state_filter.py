"""GPS-aided strapdown INS: the closed-loop error-state Kalman filter of seed 001 section 4
(eqs. 31-35, Fig. 7), with or without magnetometer attitude aiding (eqs. 36-37).

Per IMU epoch (40 Hz): mechanise (eq. 27) and predict the error covariance (the shared
kalman.kf_predict's step, by blocks: predict_covariance), Phi = I + A dT (eq. 32),
Q = B diag(q) B' dT (eq. 33).  Per GPS epoch
(5 Hz, 8 predictions per update): z = [p~ - p_GPS; v~ - v_GPS; rpy~ - rpy_MEAS] (eq. 35,
the rows available) through the shared kalman.kf_update, then feed the estimated errors back
into the INS and reset dx = 0.  All Monte Carlo runs (and the with/without-magnetometer
variants) are stepped together as one batch.  The attitude rows keep coming during a GPS
outage (the magnetometer still works).

Attitude rows (magnetometer aiding), `attitude_mode`:
* "gated" (default): heading from the magnetometer, tilt-compensated with the INS roll and
  pitch, every epoch; accelerometer roll and pitch (eq. 36 on the mean of the last 8
  samples) only when the vehicle is quasi-static, |R~ s_mean + g^n| < quasi_static_accel:
  in a turn or under acceleration the accelerometer does not measure gravity (a 20 deg bank
  in a coordinated turn reads as level).
* "paper": eqs. 36-37 literally at every GPS epoch (accelerometer tilt, heading compensated
  with it), whatever the vehicle does.
* "heading": the heading row only.
H maps the Euler-angle differences to the error state exactly to first order (so3 /
strapdown.attitude_jacobian), including the leak of the tilt and of the sensor biases into the
measured angles.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from vtrack.estimation.kalman import kf_update
from vtrack.estimation.linalg import symmetrize
from vtrack.ins.so3 import dcm_to_euler
from vtrack.ins.strapdown import (
    GRAVITY_N, NavState, attitude_jacobian, correct, error_transition, heading_from_mag,
    heading_jacobian, mechanize, process_noise, tilt_from_accel, tilt_jacobian, wrap)

DEG = np.pi / 180.0
Recorder = Callable[[int, NavState, np.ndarray], None]


@dataclass(frozen=True)
class InsFilterConfig:
    """What the filter assumes.  Defaults model the simulated consumer IMU (vtrack.sim.imu)."""

    n_states: int = 18                   # 9 = the paper's; 15 = + accel/gyro bias; 18 = + mag bias
    dt: float = 0.025                    # IMU period [P]
    accel_noise: float = 0.02            # m/s/sqrt(s)
    gyro_noise: float = 0.01 * DEG       # rad/sqrt(s)
    accel_bias: float = 0.05             # m/s^2 (initial std of the bias state)
    gyro_bias: float = 0.02 * DEG        # rad/s
    accel_bias_rw: float = 5e-4          # m/s^2/sqrt(s)
    gyro_bias_rw: float = 2e-4 * DEG     # rad/s/sqrt(s)
    mag_noise: float = 0.2               # uT per sample (18-state heading noise)
    mag_bias: float = 0.2                # uT
    mag_bias_rw: float = 2e-3            # uT/sqrt(s)
    bias_as_noise_time: float = 10.0     # 9-state: q = sigma_n^2 + sigma_b^2 T  [A]
    sigma_gps_pos: float = 2.5           # m
    sigma_gps_vel: float = 0.1           # m/s
    sigma_tilt: float = 1.5 * DEG        # accelerometer roll/pitch  [A, SEEDS 3.2: 1-2 deg]
    sigma_heading: float = 1.0 * DEG     # magnetometer heading, 9/15 states [A, SEEDS: 1-2 deg]
    attitude_mode: str = "gated"         # gated | paper | heading
    quasi_static_accel: float = 0.15     # m/s^2, gate of the accelerometer tilt rows
    declination: float = 0.0             # rad
    omega_ie: tuple[float, float, float] = (0.0, 7.2853e-5, 3.054e-6)   # ENU at 2.4 deg N
    trapezoid: bool = True               # position rule of the mechanisation
    coriolis: bool = True                # A_vv = -2 (omega_ie x)

    def psd(self) -> tuple[float, float, float, float, float]:
        """Spectral densities of Q: accel, gyro, and the accel/gyro/mag bias walks.  The
        9-state filter has no bias states, so its Q must cover them: each bias is treated as
        extra white noise whose effect over `bias_as_noise_time` T matches a constant bias
        (q_b T = sigma_b^2 T^2), the way eq. 30 lumps all sensor errors into u."""
        qa, qg = self.accel_noise**2, self.gyro_noise**2
        if self.n_states == 9:
            T = self.bias_as_noise_time
            return qa + self.accel_bias**2 * T, qg + self.gyro_bias**2 * T, 0.0, 0.0, 0.0
        return qa, qg, self.accel_bias_rw**2, self.gyro_bias_rw**2, self.mag_bias_rw**2

    def initial_covariance(self, sigma_pos: float, sigma_vel: float, sigma_tilt: float,
                           sigma_yaw: float) -> np.ndarray:
        """P0 = diag(dr, dv, eps[, dba, dbg[, dbm]]) variances."""
        d = [sigma_pos] * 3 + [sigma_vel] * 3 + [sigma_tilt] * 2 + [sigma_yaw]
        if self.n_states >= 15:
            d += [self.accel_bias] * 3 + [self.gyro_bias] * 3
        if self.n_states == 18:
            d += [self.mag_bias] * 3
        return np.diag(np.square(d))


@dataclass
class FilterStats:
    """Counts over the run: update epochs and rows of each attitude kind used."""

    updates: int = 0
    tilt_rows: int = 0
    heading_rows: int = 0


def _attitude_rows(cfg: InsFilterConfig, nav: NavState, s_mean: np.ndarray, m_b: np.ndarray,
                   aiding: np.ndarray, paper: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The [roll, pitch, yaw] rows of eq. 35: innovation z = rpy~ - rpy_MEAS (B, 3), its
    Jacobian H = dz/d(dx) (B, 3, n), the heading noise variance (B,) and the row mask (B, 3).
    s_mean and m_b are already bias-corrected with the current estimates; `paper` (B,) marks
    the elements that use eqs. 36-37 literally, the others use cfg.attitude_mode."""
    n = cfg.n_states
    B = s_mean.shape[0]
    rpy = dcm_to_euler(nav.R)
    J = attitude_jacobian(nav.R)                         # d rpy~ / d eps
    roll_a, pitch_a = tilt_from_accel(s_mean)
    mask = np.zeros((B, 3), dtype=bool)
    mask[:, 2] = aiding
    H = np.zeros((B, 3, n))
    H[:, :, 6:9] = J
    if cfg.attitude_mode == "gated":
        a_kin = np.einsum("bij,bj->bi", nav.R, s_mean) + GRAVITY_N
        still = np.linalg.norm(a_kin, axis=-1) < cfg.quasi_static_accel
        mask[:, 0:2] = (aiding & (still | paper))[:, None]
    elif cfg.attitude_mode == "heading":
        mask[:, 0:2] = (aiding & paper)[:, None]
    else:
        raise ValueError(f"unknown attitude_mode {cfg.attitude_mode!r}")
    # heading compensated with the INS tilt (whose error leaks into the measurement), or
    # with the accelerometer tilt (eq. 37 literally, `paper`)
    roll_c = np.where(paper, roll_a, rpy[:, 0])
    pitch_c = np.where(paper, pitch_a, rpy[:, 1])
    yaw_m = heading_from_mag(m_b, roll_c, pitch_c, cfg.declination)
    d_m, d_roll, d_pitch = heading_jacobian(m_b, roll_c, pitch_c)
    leak = (~paper)[:, None]
    H[:, 2, 6:9] = J[:, 2] - leak * (d_roll[:, None] * J[:, 0] + d_pitch[:, None] * J[:, 1])
    if n >= 15:      # the residual accelerometer bias moves the accelerometer tilt
        H[:, 0:2, 9:12] = -tilt_jacobian(s_mean)
    if n == 18:      # ... and the residual magnetometer bias the heading
        H[:, 2, 15:18] = -d_m
        var_yaw = cfg.mag_noise**2 * np.einsum("bi,bi->b", d_m, d_m)
    else:
        var_yaw = np.full(B, cfg.sigma_heading**2)
    nu = np.stack([rpy[:, 0] - roll_a, rpy[:, 1] - pitch_a, rpy[:, 2] - yaw_m], -1)
    return wrap(nu), H, var_yaw, mask


def predict_covariance(P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """P- = Phi P Phi' + Q (kalman.kf_predict; Phi of eq. 32, Q of eq. 33) by blocks. Phi is
    the identity on the bias rows (random walks), so only its 9 navigation rows N multiply:

        P- = [[N P N', N P[:, 9:]], [(N P[:, 9:])', P[9:, 9:]]] + Q

    (a third of the dense products' arithmetic for 18 states; exactly symmetric, the
    navigation block symmetrised as in kf_predict; 9 states: the dense step)."""
    N = F[..., :9, :]
    NP = N @ P
    out = np.empty_like(P)
    out[..., :9, :9] = symmetrize(NP @ np.swapaxes(N, -1, -2))
    out[..., :9, 9:] = NP[..., 9:]
    out[..., 9:, :9] = np.swapaxes(NP[..., 9:], -1, -2)
    out[..., 9:, 9:] = P[..., 9:, 9:]
    return out + Q


def run_ins_filter(cfg: InsFilterConfig, nav0: NavState, P0: np.ndarray, accel: np.ndarray,
                   gyro: np.ndarray, mag: np.ndarray, gps_index: np.ndarray,
                   gps_pos: np.ndarray, gps_vel: np.ndarray, gps_valid: np.ndarray,
                   mag_aiding: np.ndarray, recorder: Recorder | None = None,
                   every: int = 8, paper_attitude: np.ndarray | None = None
                   ) -> tuple[NavState, np.ndarray, FilterStats]:
    """Run the closed-loop filter over a batch of B runs.

    accel, gyro, mag: (B, K, 3) raw IMU samples at epochs 0..K-1; gps_index (J,) the IMU
    epochs of the 5 Hz update instants, gps_pos/gps_vel (B, J, 3), gps_valid (B, J) or (J,);
    mag_aiding (B,) switches the attitude rows per batch element; paper_attitude (B,) makes
    an element use eqs. 36-37 literally (default: cfg.attitude_mode == "paper").  nav0 and
    P0 (B, n, n) describe the estimate at epoch 0.  recorder(k, nav, P) is called at every
    epoch k = 0..K-1 (after the update at update epochs)."""
    n, dt = cfg.n_states, cfg.dt
    if n not in (9, 15, 18):
        raise ValueError("n_states must be 9, 15 or 18")
    B, K = accel.shape[0], accel.shape[1]
    omega_ie = np.asarray(cfg.omega_ie, dtype=float)
    valid = np.broadcast_to(np.asarray(gps_valid, dtype=bool), (B, len(gps_index)))
    aiding = np.broadcast_to(np.asarray(mag_aiding, dtype=bool), (B,))
    paper = np.broadcast_to(np.asarray(cfg.attitude_mode == "paper" if paper_attitude is None
                                       else paper_attitude, dtype=bool), (B,))
    if cfg.attitude_mode == "paper":
        cfg = replace(cfg, attitude_mode="gated")       # every element is `paper` anyway
    nav, P = nav0.copy(), np.array(P0, dtype=float)
    x = np.zeros((B, n))
    # Q (eq. 33) is constant for isotropic noise densities (R R' = I).
    Q = process_noise(np.eye(3), n, dt, *cfg.psd())
    R_gps = np.square([cfg.sigma_gps_pos] * 3 + [cfg.sigma_gps_vel] * 3)
    H = np.zeros((B, 9, n))
    H[:, 0:3, 0:3] = np.eye(3)
    H[:, 3:6, 3:6] = np.eye(3)
    Rm = np.zeros((B, 9, 9))
    idx = np.arange(8)
    Rm[:, idx, idx] = np.concatenate([R_gps, [cfg.sigma_tilt**2] * 2])
    fix_at = {int(k): j for j, k in enumerate(gps_index)}
    stats = FilterStats()
    if recorder is not None:
        recorder(0, nav, P)
    for k in range(K - 1):
        s_b = accel[:, k] - nav.ba
        w_b = gyro[:, k] - nav.bg
        s_n = (nav.R @ s_b[:, :, None])[:, :, 0]
        F = error_transition(nav.R, s_n, omega_ie, n, dt, cfg.coriolis)     # eq. 32
        nav.p, nav.v, nav.R = mechanize(nav.p, nav.v, nav.R, s_b, w_b, dt, omega_ie,
                                        cfg.trapezoid)
        P = predict_covariance(P, F, Q)         # x = 0 between updates (closed loop): F x = x
        j = fix_at.get(k + 1)
        if j is not None:
            lo = max(0, k + 2 - every)
            s_mean = accel[:, lo:k + 2].mean(axis=1) - nav.ba
            nu_att, H_att, var_yaw, m_att = _attitude_rows(
                cfg, nav, s_mean, mag[:, k + 1] - nav.bm, aiding, paper)
            mask = np.concatenate([np.repeat(valid[:, j, None], 6, axis=1), m_att], axis=1)
            if mask.any():
                nu = np.concatenate([nav.p - gps_pos[:, j], nav.v - gps_vel[:, j], nu_att], 1)
                nu = np.where(mask, nu, 0.0)                 # NaN of a missing fix -> 0
                H[:, 6:9] = H_att
                Rm[:, 8, 8] = var_yaw
                x, P, _ = kf_update(x, P, nu, H, Rm, mask)
                nav = correct(nav, x)
                x = np.zeros((B, n))
                stats.updates += 1
                stats.tilt_rows += int(m_att[:, 0].sum())
                stats.heading_rows += int(m_att[:, 2].sum())
        if recorder is not None:
            recorder(k + 1, nav, P)
    return nav, P, stats
