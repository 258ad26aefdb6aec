"""Car following by the intelligent driver model (IDM), shared by every synthetic scene.

    a* = a_max [1 - (v/v_d)^4 - (s*/g)^2],   s* = s0 + v T + v dv / (2 sqrt(a_max b))

(above the desired speed the free term is -b [1 - (v_d/v)^2]), clipped to [-b_max, a_max];
the actual acceleration follows a* with a first-order lag tau, so it is continuous. Lengths are
metres times `scale` (the overhead scene integrates in pixels: scale = pixels per metre).
"""

from __future__ import annotations

import numpy as np

S0_M = 2.0                 # standstill gap
HEADWAY_S = 1.3            # desired time gap T
B_COMFORT = 2.0            # comfortable deceleration b
B_MAX = 5.0                # deceleration limit b_max
TAU_S = 0.4                # lag of the actual behind the commanded acceleration


def idm_command(v: np.ndarray, v_d: np.ndarray, gap: np.ndarray, dv: np.ndarray,
                a_max: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """IDM command a* (module docstring), clipped to [-b_max, a_max]; gap = inf: free road."""
    b = B_COMFORT * scale
    ratio = v / v_d
    free = np.where(ratio <= 1, a_max * (1 - ratio ** 4),
                    -b * (1 - 1 / np.maximum(ratio, 1) ** 2))
    s_star = S0_M * scale + np.maximum(0, v * HEADWAY_S + v * dv / (2 * np.sqrt(a_max * b)))
    interaction = -a_max * (s_star / gap) ** 2
    return np.clip(free + interaction, -B_MAX * scale, a_max)


def desired_speed(v_desired: np.ndarray, dip_start: np.ndarray, dip_hold: np.ndarray,
                  dip_factor: np.ndarray, t: float, ramp: float = 1.5) -> np.ndarray:
    """v_d(t): the base desired speed (K,) times smooth (raised-cosine) dips (K, events)
    that start at dip_start, hold for dip_hold at dip_factor and recover over `ramp` s."""
    u = t - dip_start
    up = np.clip(u / ramp, 0, 1)
    down = np.clip((u - ramp - dip_hold) / ramp, 0, 1)
    bump = 0.5 * (1 - np.cos(np.pi * up)) - 0.5 * (1 - np.cos(np.pi * down))
    return v_desired * np.min(1 - (1 - dip_factor) * bump, axis=1)


def advance(s: np.ndarray, v: np.ndarray, a: np.ndarray, a_cmd: np.ndarray, dt: float,
            on: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of the lagged command for the vehicles `on`: a follows a* with lag tau, v stays
    >= 0 (a is then the realised dv/dt), s integrates v by the trapezoid rule."""
    a_lag = np.where(on, a + (a_cmd - a) * min(1.0, dt / TAU_S), a)
    v_new = np.where(on, np.maximum(v + a_lag * dt, 0.0), v)
    a_new = np.where(on, (v_new - v) / dt, a)
    s_new = np.where(on, s + 0.5 * (v + v_new) * dt, s)
    return s_new, v_new, a_new
