"""Seeded, deterministic vehicle trajectories for the GPS-aided INS experiment (seed 001,
section 4; SEEDS 3.2): a UAV racetrack flight and a car drive.

A trajectory is built from smooth command schedules -- speed V(t), turn rate psi'(t) and
flight-path angle gamma(t) -- whose values, rates and integrals are analytic (quintic
smoothstep transitions).  From them

    v^n = V [cos(gamma) cos(psi), cos(gamma) sin(psi), sin(gamma)]          (ENU)
    a^n = dv^n/dt  (analytic),   p^n = p0 + int v^n dt  (fine-grid trapezoid)

and the attitude R_b^n = Rz(psi) Ry(-gamma) Rx(phi): body x along the velocity (no
sideslip, no angle of attack), the UAV banked for a coordinated turn (no lateral specific
force), the car's roll fixed at 0.  Frames as in vtrack.ins.so3 (ENU / FLU).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtrack.ins.so3 import dcm_to_euler, log_so3, rot_x, rot_y, rot_z

G0 = 9.80665                        # m/s^2, seed eq. 27
GRAVITY_N = np.array([0.0, 0.0, -G0])
OMEGA_EARTH = 7.292115e-5           # rad/s (WGS-84)


def earth_rate_enu(latitude_deg: float) -> np.ndarray:
    """omega_ie^n = Omega_e [0, cos L, sin L] in a local ENU frame at latitude L."""
    lat = np.radians(latitude_deg)
    return OMEGA_EARTH * np.array([0.0, np.cos(lat), np.sin(lat)])


def _smoothstep(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """S(u) = 6u^5 - 15u^4 + 10u^3 on [0, 1] (C2), its derivative and its integral from 0."""
    uc = np.clip(u, 0.0, 1.0)
    s = uc**3 * (10.0 - 15.0 * uc + 6.0 * uc**2)
    ds = np.where((u > 0) & (u < 1), 30.0 * uc**2 * (1.0 - uc) ** 2, 0.0)
    integ = uc**6 - 3.0 * uc**5 + 2.5 * uc**4 + np.maximum(u - 1.0, 0.0)
    return s, ds, integ


@dataclass(frozen=True)
class SmoothSchedule:
    """c(t) = c0 + sum_i delta_i S((t - start_i)/ramp_i): piecewise constant with C2 ramps."""

    c0: float
    starts: tuple[float, ...] = ()
    deltas: tuple[float, ...] = ()
    ramps: tuple[float, ...] = ()

    def _eval(self, t: np.ndarray, which: int) -> np.ndarray:
        """Sum over ramps of delta_i * (S, S'/ramp_i or ramp_i * int S)[which]; each ramp only
        touches the samples inside it, later samples get its settled value (O(N + ramps))."""
        t = np.asarray(t, dtype=float)
        flat = t.ravel()
        order = np.argsort(flat, kind="stable")
        ts = flat[order]
        acc = np.zeros_like(ts)
        for st, d, rp in zip(self.starts, self.deltas, self.ramps):
            i0, i1 = np.searchsorted(ts, [st, st + rp], side="right")
            if i0 < i1:
                s, ds, integ = _smoothstep((ts[i0:i1] - st) / rp)
                acc[i0:i1] += d * (s, ds / rp, rp * integ)[which]
            if which == 0:
                acc[i1:] += d
            elif which == 2:
                acc[i1:] += d * (ts[i1:] - st - 0.5 * rp)
        out = np.empty_like(acc)
        out[order] = acc
        return out.reshape(t.shape)

    def value(self, t: np.ndarray) -> np.ndarray:
        return self.c0 + self._eval(t, 0)

    def rate(self, t: np.ndarray) -> np.ndarray:
        return self._eval(t, 1)

    def integral(self, t: np.ndarray) -> np.ndarray:
        """int_0^t c(tau) d tau (exact; schedules start after t = 0)."""
        return self.c0 * np.asarray(t, dtype=float) + self._eval(t, 2)


class _ScheduleBuilder:
    """Appends ramps to a schedule; each ramp starts when the previous one ends."""

    def __init__(self, c0: float) -> None:
        self.c0, self.current = c0, c0
        self.starts: list[float] = []
        self.deltas: list[float] = []
        self.ramps: list[float] = []

    def ramp_to(self, t: float, target: float, ramp: float) -> None:
        if target != self.current:
            self.starts.append(t)
            self.deltas.append(target - self.current)
            self.ramps.append(ramp)
            self.current = target

    def build(self) -> SmoothSchedule:
        return SmoothSchedule(self.c0, tuple(self.starts), tuple(self.deltas), tuple(self.ramps))


@dataclass(frozen=True)
class Manoeuvres:
    """The three command schedules and the vehicle type (bank in turns or not)."""

    speed: SmoothSchedule
    turn_rate: SmoothSchedule
    climb: SmoothSchedule
    coordinated_turns: bool
    heading0: float = 0.0
    p0: tuple[float, float, float] = (0.0, 0.0, 0.0)


def uav_racetrack(duration: float, rng: np.random.Generator, speed: float = 40.0,
                  bank_deg: float = 20.0) -> Manoeuvres:
    """A ~40 m/s racetrack flight with left 180 deg turns at about `bank_deg` of bank, random
    straight-leg lengths, occasional 90 deg S-turn pairs, climbs/descents and speed changes
    (SEEDS 3.2 [A]; the paper's UAV averaged 145 km/h)."""
    turn = G0 * np.tan(np.radians(bank_deg)) / speed
    roll_in = 3.0
    V, W, C = _ScheduleBuilder(speed), _ScheduleBuilder(0.0), _ScheduleBuilder(0.0)
    t, alt = 10.0, 300.0
    while t < duration:
        leg = rng.uniform(25.0, 45.0)
        # a climb or descent (back towards 300 m), or a speed change, somewhere on the leg
        if rng.uniform() < 0.5:
            sign = -1.0 if alt > 300.0 else 1.0
            gam = np.radians(3.0 * sign * rng.choice([1.0, 1.0, -1.0]))
            C.ramp_to(t + 2.0, gam, 3.0)
            C.ramp_to(t + leg - 8.0, 0.0, 3.0)
            alt += V.current * np.sin(gam) * (leg - 10.0)
        else:
            V.ramp_to(t + 2.0, float(np.clip(V.current + rng.choice([-5.0, 5.0]), 32, 48)), 5.0)
        t += leg
        if rng.uniform() < 0.3:              # S-turn: 90 deg right then 90 deg left
            for sgn in (-1.0, 1.0):
                hold = (np.pi / 2) / turn - roll_in
                W.ramp_to(t, sgn * turn, roll_in)
                W.ramp_to(t + roll_in + hold, 0.0, roll_in)
                t += 2 * roll_in + hold + rng.uniform(8.0, 15.0)
        hold = np.pi / turn - roll_in         # 180 deg left turn: turn * (hold + ramp) = pi
        W.ramp_to(t, turn, roll_in)
        W.ramp_to(t + roll_in + hold, 0.0, roll_in)
        t += 2 * roll_in + hold
    return Manoeuvres(V.build(), W.build(), C.build(), coordinated_turns=True,
                      heading0=float(rng.uniform(-np.pi, np.pi)), p0=(0.0, 0.0, 300.0))


def car_drive(duration: float, rng: np.random.Generator, cruise: float = 15.0) -> Manoeuvres:
    """A car on a street grid: accelerate, cruise at 10-18 m/s, slow to 8 m/s for 90 deg
    corners (about 0.2 rad/s, lateral ~1.6 m/s^2), gentle grades of +-2 deg, and a stop
    (SEEDS 3.2 [A]; the paper's offline car test)."""
    V, W, C = _ScheduleBuilder(0.0), _ScheduleBuilder(0.0), _ScheduleBuilder(0.0)
    V.ramp_to(5.0, cruise, 10.0)
    t = 20.0
    while t < duration:
        leg = rng.uniform(20.0, 40.0)
        target = float(rng.uniform(10.0, 18.0))
        V.ramp_to(t + 1.0, target, 6.0)
        C.ramp_to(t + 2.0, np.radians(rng.uniform(-2.0, 2.0)), 5.0)
        if rng.uniform() < 0.15:              # a stop on the leg
            V.ramp_to(t + 10.0, 0.0, 8.0)
            V.ramp_to(t + 24.0, target, 8.0)
            leg += 14.0
        t += leg
        V.ramp_to(t - 5.0, 8.0, 4.0)           # slow down for the corner
        rate = 0.2 * rng.choice([-1.0, 1.0])
        ramp = 2.0
        hold = (np.pi / 2) / abs(rate) - ramp
        W.ramp_to(t, rate, ramp)
        W.ramp_to(t + ramp + hold, 0.0, ramp)
        t += 2 * ramp + hold
    return Manoeuvres(V.build(), W.build(), C.build(), coordinated_turns=False,
                      heading0=float(rng.uniform(-np.pi, np.pi)))


@dataclass
class Trajectory:
    """Truth at the IMU epochs t_k = k dT: p (K, 3), v (K, 3), a (K, 3), R (K, 3, 3)."""

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    R: np.ndarray
    dt: float
    omega_ie: np.ndarray

    @property
    def rpy(self) -> np.ndarray:
        """[roll, pitch, yaw] (K, 3)."""
        return dcm_to_euler(self.R)


def _kinematics(m: Manoeuvres, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """v^n, a^n and R_b^n at times t (all analytic in t)."""
    V, Vd = m.speed.value(t), m.speed.rate(t)
    psi = m.heading0 + m.turn_rate.integral(t)
    psid = m.turn_rate.value(t)
    gam, gamd = m.climb.value(t), m.climb.rate(t)
    cg, sg, cp, sp = np.cos(gam), np.sin(gam), np.cos(psi), np.sin(psi)
    u = np.stack([cg * cp, cg * sp, sg], -1)
    du_dpsi = np.stack([-cg * sp, cg * cp, np.zeros_like(t)], -1)
    du_dgam = np.stack([-sg * cp, -sg * sp, cg], -1)
    v = V[..., None] * u
    a = Vd[..., None] * u + V[..., None] * (psid[..., None] * du_dpsi + gamd[..., None] * du_dgam)
    Ryz = rot_z(psi) @ rot_y(-gam)
    if m.coordinated_turns:
        f = np.einsum("...ji,...j->...i", Ryz, a - GRAVITY_N)   # specific force before roll
        roll = np.arctan2(-f[..., 1], f[..., 2])                 # zero body-y specific force
    else:
        roll = np.zeros_like(t)
    return v, a, Ryz @ rot_x(roll)


def generate(m: Manoeuvres, duration: float, dt: float = 0.025, latitude_deg: float = 2.4,
             substeps: int = 8) -> Trajectory:
    """Sample the truth at t_k = k dT, k = 0..round(duration/dT). Position integrates v on a
    grid dT/substeps (trapezoid; error below a millimetre over 20 min)."""
    n = int(round(duration / dt)) + 1
    tf = np.arange((n - 1) * substeps + 1) * (dt / substeps)
    vf, _, _ = _kinematics(m, tf)
    steps = 0.5 * (vf[1:] + vf[:-1]) * (dt / substeps)
    pf = np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)]) + np.asarray(m.p0)
    t = tf[::substeps]
    v, a, R = _kinematics(m, t)
    return Trajectory(t=t, p=pf[::substeps], v=v, a=a, R=R, dt=dt,
                      omega_ie=earth_rate_enu(latitude_deg))


def body_rates(m: Manoeuvres, t: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """omega_nb^b(t) by a central difference of R: log(R(t-h)' R(t+h)) / 2h (error O(h^2))."""
    _, _, Rm = _kinematics(m, t - h)
    _, _, Rp = _kinematics(m, t + h)
    return log_so3(np.swapaxes(Rm, -1, -2) @ Rp) / (2.0 * h)
