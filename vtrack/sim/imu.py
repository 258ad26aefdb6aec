"""Consumer-grade IMU (accelerometer, gyroscope, magnetometer) at 40 Hz and a 5 Hz GPS for
the GPS-aided INS experiment (seed 001 section 4, SEEDS 3.2).  Seeded and deterministic.

Every inertial channel is  measurement = ideal + bias_k + white noise,  with
bias_0 ~ N(0, sigma_b^2 I) and bias_{k+1} = bias_k + N(0, sigma_rw^2 dT I) (random walk).
A white-noise density sigma [unit/sqrt(s)] gives a per-sample std of sigma / sqrt(dT).

The ideal samples come in two flavours:
* "increment" (default): what an IMU that outputs velocity and angle increments delivers,
  referred to the body frame at the start of the interval:
      omega_k = log(R_k' R_{k+1}) / dT + R_k' omega_ie^n,
      s_k     = R_k' [ (v_{k+1} - v_k) / dT - g^n + 2 omega_ie^n x v_k ];
  the corrected eq. 27 then reproduces v and R exactly and p to second order.
* "sample": instantaneous values omega_nb^b(t_k) + R_k' omega_ie^n and
  R_k' (a^n(t_k) - g^n + 2 omega_ie^n x v_k): independent of the mechanisation, used to test it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vtrack.ins.so3 import log_so3
from vtrack.sim.ins_trajectory import GRAVITY_N, Manoeuvres, Trajectory, body_rates

DEG = np.pi / 180.0


@dataclass(frozen=True)
class ImuSpec:
    """Consumer MEMS values of SEEDS 3.2 (noise densities and turn-on bias std) plus our
    assumed [A] bias random walks and magnetometer errors. SI units (rad, m/s^2, uT)."""

    accel_noise: float = 0.02               # m/s/sqrt(s)              [SEEDS 3.2]
    accel_bias: float = 0.05                # m/s^2 turn-on std        [SEEDS 3.2]
    accel_bias_rw: float = 5e-4             # m/s^2/sqrt(s)            [A]
    gyro_noise: float = 0.01 * DEG          # rad/sqrt(s)  (0.01 deg/sqrt(s))   [SEEDS 3.2]
    gyro_bias: float = 0.02 * DEG           # rad/s        (0.02 deg/s)         [SEEDS 3.2]
    gyro_bias_rw: float = 2e-4 * DEG        # rad/s/sqrt(s)            [A]
    mag_noise: float = 0.2                  # uT per sample            [A]
    mag_bias: float = 0.2                   # uT residual hard iron after calibration [A]
    mag_bias_rw: float = 2e-3               # uT/sqrt(s)               [A]
    field_strength: float = 41.0            # uT                       [A] (near Mersing, MY)
    inclination_deg: float = -12.0          # dip, positive downward   [A]
    declination_deg: float = 0.0            # [A]
    dt: float = 0.025                       # 40 Hz                    [P]

    def field_n(self) -> np.ndarray:
        """Earth field in ENU: B [cos I sin D, cos I cos D, -sin I]."""
        inc, dec = np.radians(self.inclination_deg), np.radians(self.declination_deg)
        return self.field_strength * np.array([np.cos(inc) * np.sin(dec),
                                               np.cos(inc) * np.cos(dec), -np.sin(inc)])

    def perfect(self) -> ImuSpec:
        """The same geometry with every error switched off."""
        from dataclasses import replace

        return replace(self, accel_noise=0.0, accel_bias=0.0, accel_bias_rw=0.0,
                       gyro_noise=0.0, gyro_bias=0.0, gyro_bias_rw=0.0, mag_noise=0.0,
                       mag_bias=0.0, mag_bias_rw=0.0)


@dataclass
class ImuData:
    """Samples at the IMU epochs (K, 3) and the true biases that produced them."""

    accel: np.ndarray
    gyro: np.ndarray
    mag: np.ndarray
    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    mag_bias: np.ndarray


def ideal_imu(traj: Trajectory, mode: str = "increment",
              manoeuvres: Manoeuvres | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Error-free specific force s^b and angular rate omega_ib^b at every epoch (K, 3)."""
    Rt = np.swapaxes(traj.R, -1, -2)
    coriolis = 2.0 * np.cross(traj.omega_ie, traj.v)
    earth_b = np.einsum("kij,j->ki", Rt, traj.omega_ie)
    if mode == "increment":
        acc_n = np.diff(traj.v, axis=0) / traj.dt
        w_nb = log_so3(Rt[:-1] @ traj.R[1:]) / traj.dt
        acc_n = np.vstack([acc_n, acc_n[-1:]])          # the last epoch only feeds the mag
        w_nb = np.vstack([w_nb, w_nb[-1:]])
    elif mode == "sample":
        if manoeuvres is None:
            raise ValueError("mode 'sample' needs the manoeuvres")
        acc_n = traj.a
        w_nb = body_rates(manoeuvres, traj.t)
    else:
        raise ValueError(f"unknown IMU mode {mode!r}")
    s_b = np.einsum("kij,kj->ki", Rt, acc_n - GRAVITY_N + coriolis)
    return s_b, w_nb + earth_b


def _bias_walk(rng: np.random.Generator, k: int, sigma0: float, rw: float, dt: float
               ) -> np.ndarray:
    b0 = rng.normal(0.0, 1.0, 3) * sigma0
    steps = rng.normal(0.0, 1.0, (k - 1, 3)) * (rw * np.sqrt(dt))
    return b0 + np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])


def simulate_imu(traj: Trajectory, spec: ImuSpec, rng: np.random.Generator,
                 mode: str = "increment", manoeuvres: Manoeuvres | None = None) -> ImuData:
    """Noisy 3-axis accelerometer, gyro and magnetometer samples (module docstring)."""
    k = len(traj.t)
    s_b, w_ib = ideal_imu(traj, mode, manoeuvres)
    ba = _bias_walk(rng, k, spec.accel_bias, spec.accel_bias_rw, spec.dt)
    bg = _bias_walk(rng, k, spec.gyro_bias, spec.gyro_bias_rw, spec.dt)
    bm = _bias_walk(rng, k, spec.mag_bias, spec.mag_bias_rw, spec.dt)
    sq = 1.0 / np.sqrt(spec.dt)
    accel = s_b + ba + rng.normal(0.0, 1.0, (k, 3)) * (spec.accel_noise * sq)
    gyro = w_ib + bg + rng.normal(0.0, 1.0, (k, 3)) * (spec.gyro_noise * sq)
    mag_b = np.einsum("kji,j->ki", traj.R, spec.field_n())
    mag = mag_b + bm + rng.normal(0.0, 1.0, (k, 3)) * spec.mag_noise
    return ImuData(accel=accel, gyro=gyro, mag=mag, accel_bias=ba, gyro_bias=bg, mag_bias=bm)


@dataclass(frozen=True)
class GpsSpec:
    """5 Hz GPS position and velocity fixes with white noise [P rate; SEEDS 3.2 sigmas]."""

    every: int = 8                           # IMU epochs per fix (40 Hz / 5 Hz)  [P]
    sigma_pos: float = 2.5                   # m, per axis                        [SEEDS 3.2]
    sigma_vel: float = 0.1                   # m/s, per axis                      [SEEDS 3.2]
    outages: tuple[tuple[float, float], ...] = field(default_factory=tuple)  # [t0, t1) s


@dataclass
class GpsData:
    """Fixes at IMU epochs `index` (J,): pos (J, 3), vel (J, 3); valid False in outages."""

    index: np.ndarray
    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    valid: np.ndarray


def simulate_gps(traj: Trajectory, spec: GpsSpec, rng: np.random.Generator) -> GpsData:
    """A fix at every `every`-th IMU epoch after t = 0; none inside an outage window."""
    idx = np.arange(spec.every, len(traj.t), spec.every)
    t = traj.t[idx]
    valid = np.ones(len(idx), dtype=bool)
    for t0, t1 in spec.outages:
        valid &= ~((t >= t0) & (t < t1))
    pos = traj.p[idx] + rng.normal(0.0, spec.sigma_pos, (len(idx), 3))
    vel = traj.v[idx] + rng.normal(0.0, spec.sigma_vel, (len(idx), 3))
    pos[~valid] = np.nan
    vel[~valid] = np.nan
    return GpsData(index=idx, t=t, pos=pos, vel=vel, valid=valid)
