"""The GPS-aided INS error-state filter (seed 001 eqs. 31-37): measurement Jacobians, GPS
outages (error growth, covariance coverage, reconvergence), magnetometer aiding, and the
batch of runs (equal to each run stepped alone) with the experiment's recorder."""

import numpy as np
import pytest

from vtrack.estimation.bounds import chi2_band, nees
from vtrack.ins.strapdown import (GRAVITY_N, NavState, attitude_error, error_transition,
                                  process_noise)
from vtrack.estimation.kalman import kf_predict
from vtrack.ins.error_state_filter import (InsFilterConfig, _attitude_rows, predict_covariance,
                                           run_ins_filter)
from vtrack.ins.so3 import euler_to_dcm, exp_so3
from vtrack.experiments import ins
from vtrack.sim.imu import ImuSpec

RUNS = 12
OUTAGE = (70.0, 100.0)


@pytest.mark.parametrize("n", [9, 15, 18])
def test_the_block_prediction_is_the_dense_one(n):
    """predict_covariance (Phi's bias rows are the identity) gives kf_predict's F P F' + Q to
    rounding, exactly symmetric, for a stack of attitudes and specific forces."""
    rng = np.random.default_rng(n)
    R = exp_so3(rng.normal(size=(6, 3)))
    F = error_transition(R, rng.normal(0.0, 5.0, (6, 3)), np.array([0.0, 7e-5, 3e-6]), n,
                         0.025)
    A = rng.normal(size=(6, n, n))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(n)
    Q = process_noise(np.eye(3), n, 0.025, 4e-4, 3e-8, 2.5e-7, 1e-14, 4e-6)
    got = predict_covariance(P, F, Q)
    want = kf_predict(np.zeros((6, n)), P, F, Q)[1]
    assert np.array_equal(got, np.swapaxes(got, -1, -2))
    np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-14 * np.abs(want).max())


def test_attitude_rows_jacobian_matches_the_measurement():
    """z = rpy~ - rpy_MEAS for an INS that is off the truth by (eps, dba, dbm) equals H dx to
    first order (gated mode: accelerometer tilt when quasi-static, heading tilt-compensated
    with the INS angles; steep field so that the tilt leak matters)."""
    rng = np.random.default_rng(5)
    spec = ImuSpec(inclination_deg=60.0, declination_deg=3.0)
    cfg = InsFilterConfig(n_states=18, declination=np.radians(3.0))
    R = euler_to_dcm(np.array([[0.2, -0.1, 1.0], [-0.4, 0.3, -2.5], [0.05, 0.0, 3.0]]))
    B = len(R)
    b_a, b_m = rng.normal(size=(B, 3)) * 0.05, rng.normal(size=(B, 3)) * 0.5
    s_raw = np.swapaxes(R, 1, 2) @ -GRAVITY_N + b_a
    m_raw = np.swapaxes(R, 1, 2) @ spec.field_n() + b_m
    for scale in (1e-4, 5e-5):
        dx = np.zeros((B, 18))
        dx[:, 6:9] = rng.normal(size=(B, 3)) * scale
        dx[:, 9:12] = rng.normal(size=(B, 3)) * scale * 10
        dx[:, 15:18] = rng.normal(size=(B, 3)) * scale * 100
        z0 = np.zeros((B, 3))
        nav = NavState(z0, z0, exp_so3(-dx[:, 6:9]) @ R, b_a - dx[:, 9:12], z0,
                       b_m - dx[:, 15:18])
        nu, H, var_yaw, mask = _attitude_rows(cfg, nav, s_raw - nav.ba, m_raw - nav.bm,
                                              np.ones(B, bool), np.zeros(B, bool))
        assert mask.all() and np.all(var_yaw > 0)
        lin = np.einsum("bij,bj->bi", H, dx)
        np.testing.assert_allclose(nu, lin, atol=50 * scale**2 * 100)


@pytest.fixture(scope="module")
def outage_run():
    scn = ins.Scenario(duration=150.0, outages=(OUTAGE,))
    batch = ins.simulate(scn, RUNS, 2024)
    series = ins.run_variant(batch, scn, ins.filter_config(scn, 18))
    return batch, series


def _err(s):
    return np.linalg.norm(s.pos_err.astype(float), axis=-1)


def test_outage_error_grows_and_covariance_covers_it(outage_run):
    """During a 30 s GPS outage the position error grows well above its aided level, and the
    filter's covariance covers it: the run-averaged position NEES, averaged over the outage,
    lies in the 99% chi2 band of ONE epoch's run average (lenient: epochs are correlated, the
    time average varies less), and every axis error stays within 3 sigma at >= 97% of the
    (run, epoch) pairs (0.997 expected for a consistent Gaussian filter)."""
    batch, series = outage_run
    t = batch.traj.t
    inside = (t >= OUTAGE[0]) & (t < OUTAGE[1])
    before = (t >= OUTAGE[0] - 30) & (t < OUTAGE[0])
    end = np.searchsorted(t, OUTAGE[1]) - 1
    lo, hi = chi2_band(3, RUNS, 0.99)
    for label, s in series.items():
        e = _err(s)
        pre = np.sqrt(np.mean(e[:, before] ** 2))
        at_end = np.sqrt(np.mean(e[:, end] ** 2))
        assert at_end > 5 * pre, label
        sig_end = np.sqrt(np.mean(np.sum(s.pos_sig[:, end] ** 2, axis=-1)))
        assert sig_end > 5 * np.sqrt(np.mean(np.sum(s.pos_sig[:, before] ** 2, axis=-1)))
        assert lo < s.nees_pos[:, inside].mean() < hi, label
        cover = np.abs(s.pos_err[:, inside]) <= 3 * s.pos_sig[:, inside]
        assert cover.mean() >= 0.97, label


def test_filter_reconverges_after_the_outage(outage_run):
    """10-30 s after GPS returns the position RMSE is back within 2x its pre-outage value
    and the position covariance has shrunk back to within 2x its pre-outage trace."""
    batch, series = outage_run
    t = batch.traj.t
    before = (t >= OUTAGE[0] - 30) & (t < OUTAGE[0])
    after = (t >= OUTAGE[1] + 10) & (t < OUTAGE[1] + 30)
    for label, s in series.items():
        e = _err(s)
        assert np.sqrt(np.mean(e[:, after] ** 2)) < 2 * np.sqrt(np.mean(e[:, before] ** 2))
        tr = np.sum(s.pos_sig**2, axis=-1)
        assert tr[:, after].mean() < 2 * tr[:, before].mean(), label


def test_aided_filter_is_consistent(outage_run):
    """Outside the outage and after the first 10 s: position ANEES within [2, 4] (3 dof)
    and the full 18-state ANEES within +-25% of 18 (time averages; honest, loose bounds)."""
    batch, series = outage_run
    t = batch.traj.t
    aided = (t > 10) & ((t < OUTAGE[0]) | (t > OUTAGE[1] + 10))
    k_full = np.arange(0, len(t), 4)
    aided_full = aided[k_full]
    for label, s in series.items():
        assert 2.0 < s.nees_pos[:, aided].mean() < 4.0, label
        assert 0.75 * 18 < s.nees_full[:, aided_full].mean() < 1.25 * 18, label


def test_magnetometer_bounds_heading_better_than_gps_alone(outage_run):
    """Paired (same data, same initial error): with the magnetometer the heading RMSE after
    the first 20 s is lower in every run and at most half of the GPS-only one on average."""
    batch, series = outage_run
    late = batch.traj.t > 20
    head = {k: np.sqrt(np.mean(s.yaw_err[:, late] ** 2, axis=1)) for k, s in series.items()}
    assert np.all(head["mag"] < head["no-mag"])
    assert head["mag"].mean() < 0.5 * head["no-mag"].mean()


def test_nine_state_paper_filter_tracks_gps():
    """The paper's 9-state filter (biases lumped into Q) keeps the position within 20% of the
    18-state filter's RMSE on the same data (the position is GPS-driven either way)."""
    scn = ins.Scenario(duration=60.0)
    batch = ins.simulate(scn, 4, 1)
    r9 = ins.metrics(ins.run_variant(batch, scn, ins.filter_config(scn, 9), ("mag",))["mag"],
                     batch)
    r18 = ins.metrics(ins.run_variant(batch, scn, ins.filter_config(scn, 18), ("mag",))["mag"],
                      batch)
    assert r9["rmse"] < 1.2 * r18["rmse"]
    assert r9["anees_dof"] == 9 and r18["anees_dof"] == 18


def test_batched_filter_equals_each_run_stepped_alone():
    """run_variant steps every run and label of a chunk as one batch of the filter (states
    (B, n), covariances (B, n, n)); stacked=False steps each run and label alone, a batch of
    one through the same code. Every recorded series agrees within the golden tests'
    tolerance (they are the same numbers: a run's arithmetic does not see the batch)."""
    scn = ins.Scenario(duration=20.0, outages=((8.0, 12.0),))
    batch = ins.simulate(scn, 3, 7)
    for n, labels in ((18, ("mag", "no-mag", "mag-paper")), (9, ("mag", "no-mag"))):
        cfg = ins.filter_config(scn, n)
        together = ins.run_variant(batch, scn, cfg, labels, example_every=8)
        alone = ins.run_variant(batch, scn, cfg, labels, example_every=8, stacked=False)
        for label in labels:
            a, b = together[label], alone[label]
            for name in ("pos_err", "pos_sig", "vel_err", "att_err", "yaw_err", "yaw_sig",
                         "nees_pos", "nees_full"):
                np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-9,
                                           atol=0, err_msg=f"{n} {label} {name}")
            for name in ("nav", "P"):
                np.testing.assert_allclose(a.example[name], b.example[name], rtol=1e-9)


def test_records_are_the_filter_states_at_every_epoch():
    """The experiment's recorder (buffered over blocks of epochs, reduced to errors when a
    block is full) holds, at every epoch, the error of the solution the filter handed it:
    checked against a plain per-epoch recorder over more epochs than one block."""
    scn = ins.Scenario(duration=10.0)
    batch = ins.simulate(scn, 2, 3)
    cfg = ins.filter_config(scn, 15)
    K = batch.accel.shape[1]
    assert K > 1.5 * ins._Records.BLOCK
    got = ins.run_variant(batch, scn, cfg, ("mag",))["mag"]
    t = batch.traj
    rows = np.arange(2)
    nav0 = NavState(t.p[0] + batch.init_err[:, 0:3], t.v[0] + batch.init_err[:, 3:6],
                    exp_so3(-batch.init_err[:, 6:9]) @ t.R[0], *[np.zeros((2, 3))] * 3)
    P0 = cfg.initial_covariance(scn.init_pos, scn.init_vel, np.radians(scn.init_tilt_deg),
                                np.radians(scn.init_yaw_deg))
    seen = {"p": np.zeros((2, K, 3)), "sig": np.zeros((2, K, 3)), "nees": []}

    def plain(k, nav, P):
        seen["p"][:, k] = nav.p
        seen["sig"][:, k] = np.sqrt(np.diagonal(P[:, 0:3, 0:3], axis1=-2, axis2=-1))
        if k % 4 == 0:
            e = np.concatenate([nav.p - t.p[k], nav.v - t.v[k], attitude_error(nav.R, t.R[k]),
                                batch.ba[:, k] - nav.ba, batch.bg[:, k] - nav.bg], axis=1)
            seen["nees"].append(nees(e, P))

    run_ins_filter(cfg, nav0, P0[None].repeat(2, axis=0), batch.accel[rows], batch.gyro[rows],
                   batch.mag[rows], batch.gps_index, batch.gps_pos[rows], batch.gps_vel[rows],
                   batch.gps_valid, np.ones(2, bool), plain)
    np.testing.assert_array_equal(got.pos_err, (seen["p"] - t.p).astype(np.float32))
    np.testing.assert_array_equal(got.pos_sig, seen["sig"].astype(np.float32))
    np.testing.assert_allclose(got.nees_full, np.array(seen["nees"]).T, rtol=1e-9)
