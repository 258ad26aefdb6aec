"""Rotations, the accelerometer/magnetometer attitude formulas (seed 001 eqs. 36-37, standard
form, SEEDS 3.2) and the Jacobians the INS filter uses, against known rotations and finite
differences."""

import numpy as np
import pytest

from vtrack.ins.strapdown import (
    G0, GRAVITY_N, attitude_from_accel_mag, attitude_jacobian, heading_from_mag,
    heading_jacobian, tilt_from_accel, tilt_jacobian, wrap)
from vtrack.ins.so3 import (
    dcm_to_euler, euler_rate_matrix, euler_to_dcm, exp_so3, log_so3, rot_z, skew)
from vtrack.sim.imu import ImuSpec


def _random_rpy(rng, n, max_pitch_deg=75.0):
    return np.stack([rng.uniform(-np.pi, np.pi, n) * 0.9,
                     np.radians(rng.uniform(-max_pitch_deg, max_pitch_deg, n)),
                     rng.uniform(-np.pi, np.pi, n)], axis=-1)


def test_exp_log_and_euler_round_trips():
    rng = np.random.default_rng(0)
    axis = rng.normal(size=(50, 3))
    phi = axis / np.linalg.norm(axis, axis=1, keepdims=True) * rng.uniform(1e-9, 3.0, (50, 1))
    R = exp_so3(phi)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-14)
    np.testing.assert_allclose(log_so3(R), phi, atol=1e-12)
    rpy = _random_rpy(rng, 50)
    np.testing.assert_allclose(dcm_to_euler(euler_to_dcm(rpy)), rpy, atol=1e-12)
    w = rng.normal(size=3)
    np.testing.assert_allclose(skew(w) @ np.array([1.0, -2.0, 0.5]),
                               np.cross(w, [1.0, -2.0, 0.5]), atol=1e-15)


def test_euler_rate_matrix_is_the_nav_frame_derivative():
    """exp(skew(M d)) R(rpy) = R(rpy + d) to first order."""
    rng = np.random.default_rng(1)
    for rpy in _random_rpy(rng, 20):
        d = rng.normal(size=3) * 1e-6
        lhs = exp_so3(euler_rate_matrix(rpy) @ d) @ euler_to_dcm(rpy)
        np.testing.assert_allclose(lhs, euler_to_dcm(rpy + d), atol=1e-11)


def test_accelerometer_and_magnetometer_recover_a_known_rotation():
    """Rotate gravity and an inclined, declined Earth field into the body and get the
    Euler angles back (the convention check SEEDS 3.2 asks for)."""
    rng = np.random.default_rng(2)
    spec = ImuSpec(inclination_deg=55.0, declination_deg=-7.0)
    m_n = spec.field_n()
    rpy = _random_rpy(rng, 200)
    R = euler_to_dcm(rpy)
    Rt = np.swapaxes(R, 1, 2)
    s_b = Rt @ -GRAVITY_N                     # at rest the accelerometer reads +g up
    m_b = Rt @ m_n
    got = attitude_from_accel_mag(s_b, m_b, np.radians(spec.declination_deg))
    np.testing.assert_allclose(wrap(got - rpy), 0.0, atol=1e-10)


def test_physical_conventions():
    """Level and at rest the FLU accelerometer reads [0, 0, +g]; nose pointing North is yaw
    = +90 deg (ENU, counter-clockwise from East); a right-wing-down bank is a positive roll."""
    m_n = ImuSpec(inclination_deg=30.0).field_n()
    north = rot_z(np.pi / 2)                       # body x along North
    s_b = north.T @ -GRAVITY_N
    np.testing.assert_allclose(s_b, [0, 0, G0], atol=1e-12)
    rpy = attitude_from_accel_mag(s_b, north.T @ m_n)
    np.testing.assert_allclose(rpy, [0, 0, np.pi / 2], atol=1e-12)
    roll, _ = tilt_from_accel(np.array([0.0, G0 * np.sin(0.3), G0 * np.cos(0.3)]))
    R = euler_to_dcm(np.array([0.3, 0.0, 0.0]))
    assert roll == pytest.approx(0.3)
    assert (R @ [0.0, -1.0, 0.0])[2] < 0           # the right wing (-y in FLU) goes down


def test_heading_and_tilt_jacobians_match_finite_differences():
    rng = np.random.default_rng(3)
    m = rng.normal(size=(30, 3)) * 30 + np.array([0, 30, -20])
    roll, pitch = rng.uniform(-0.6, 0.6, 30), rng.uniform(-0.6, 0.6, 30)
    d_m, d_roll, d_pitch = heading_jacobian(m, roll, pitch)
    h = 1e-6
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        fd = wrap(heading_from_mag(m + e, roll, pitch) - heading_from_mag(m - e, roll, pitch))
        np.testing.assert_allclose(d_m[:, i], fd / (2 * h), rtol=1e-5, atol=1e-9)
    fd = wrap(heading_from_mag(m, roll + h, pitch) - heading_from_mag(m, roll - h, pitch))
    np.testing.assert_allclose(d_roll, fd / (2 * h), rtol=1e-5, atol=1e-8)
    fd = wrap(heading_from_mag(m, roll, pitch + h) - heading_from_mag(m, roll, pitch - h))
    np.testing.assert_allclose(d_pitch, fd / (2 * h), rtol=1e-5, atol=1e-8)
    s = rng.normal(size=(30, 3)) + [0, 0, G0]
    J = tilt_jacobian(s)
    for i in range(3):
        e = np.zeros(3)
        e[i] = 1e-6
        fd = (np.stack(tilt_from_accel(s + e), -1) - np.stack(tilt_from_accel(s - e), -1)) / 2e-6
        np.testing.assert_allclose(J[:, :, i], fd, rtol=1e-5, atol=1e-9)


def test_attitude_jacobian_maps_eps_to_euler_differences():
    """R~ = exp(-[eps x]) R  =>  rpy(R~) - rpy(R) = attitude_jacobian(R~) eps + O(eps^2);
    near level it is -I (the sign the paper's H = I9 misses)."""
    rng = np.random.default_rng(4)
    rpy = _random_rpy(rng, 20, max_pitch_deg=60.0)
    R = euler_to_dcm(rpy)
    eps = rng.normal(size=(20, 3)) * 1e-6
    R_est = exp_so3(-eps) @ R
    J = attitude_jacobian(R_est)
    diff = wrap(dcm_to_euler(R_est) - rpy)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", J, eps), diff, atol=1e-11)
    np.testing.assert_allclose(attitude_jacobian(np.eye(3)), -np.eye(3), atol=1e-15)
