"""Seed 000 bearings-only set-up shared by the estimation tests (SEEDS.md 2.2, 2.3).

Plain helper module (not a test): the deduced two-sensor geometry, the Wiener-velocity
model, the toolbox's turning truth and a model-matched truth drawn from the filter's own
model, and a loop that runs one core filter over a measurement sequence.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from vtrack.filter_kinds import make_filter
from vtrack.estimation.linalg import wrap_angle
from vtrack.estimation.models import Bearings, WienerVelocity

DT = 0.01
Q_SPECTRAL = 0.1
SIGMA = 0.05
SENSORS = np.array([[1.0, -2.0], [1.0, 2.0]])  # deduced seed-000 geometry
M0_FILTER = np.zeros(4)                          # the paper's prior mean (turning path)
M0_TRUE = np.array([0.0, 0.0, 1.0, 0.0])         # true start; model-matched prior mean
P0 = np.diag([0.1, 0.1, 10.0, 10.0])


def models(sensors=SENSORS, sigma=SIGMA, q=Q_SPECTRAL):
    return WienerVelocity(q), Bearings(np.asarray(sensors, float), sigma)


def turning_truth(rng: np.random.Generator, steps: int = 500) -> np.ndarray:
    """The toolbox demo's coordinated-turn path (SEEDS 2.3), states after each step (K, 4)."""
    a = np.zeros(steps)
    for seg in (slice(49, 100), slice(199, 250), slice(349, 400)):
        k = len(a[seg])
        a[seg] = (np.pi / 2) / 51 / DT + 0.01 * rng.standard_normal(k)
    x = M0_TRUE.copy()
    out = np.empty((steps, 4))
    for i in range(steps):
        x = turn_transition(a[i], DT) @ x
        out[i] = x
    return out


def turn_transition(a: float, dt: float) -> np.ndarray:
    """expm(Fc dt) for Fc = [[0,0,1,0],[0,0,0,1],[0,0,0,a],[0,0,-a,0]] in closed form (the
    velocity turns clockwise at rate a); scipy's expm is ~100x slower per call."""
    if a == 0.0:
        return np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    s, c = np.sin(a * dt), np.cos(a * dt)
    return np.array([[1, 0, s / a, (1 - c) / a], [0, 1, -(1 - c) / a, s / a],
                     [0, 0, c, s], [0, 0, -s, c]])


def turn_transition_expm(a: float, dt: float) -> np.ndarray:
    """The same by scipy.linalg.expm, as the toolbox computes it (for checking)."""
    Fc = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, a], [0, 0, -a, 0]], float)
    return expm(Fc * dt)


def model_matched_truth(rng: np.random.Generator, runs: int, steps: int,
                        m0=M0_TRUE, P0_true=P0, q=Q_SPECTRAL) -> np.ndarray:
    """x0 ~ N(m0, P0), x_k = F x_{k-1} + w_k, w ~ N(0, Q): states after each step,
    shape (runs, steps, 4), drawn from the filter's own Wiener-velocity model."""
    motion = WienerVelocity(q)
    F, Q = motion.transition(DT), motion.Q(DT)
    LQ = np.linalg.cholesky(Q)
    x = m0 + rng.standard_normal((runs, 4)) @ np.linalg.cholesky(P0_true).T
    w = rng.standard_normal((steps, runs, 4)) @ LQ.T
    out = np.empty((runs, steps, 4))
    for k in range(steps):
        x = x @ F.T + w[k]
        out[:, k] = x
    return out


def bearings(states: np.ndarray, rng: np.random.Generator, sensors=SENSORS,
             sigma=SIGMA) -> np.ndarray:
    """Noisy bearings of states (..., 4) from each sensor, wrapped to (-pi, pi]."""
    z = Bearings(np.asarray(sensors, float), sigma).h(states)
    return wrap_angle(z + sigma * rng.standard_normal(z.shape))


def run(kind: str, zs: np.ndarray, x0=M0_FILTER, P0_=P0, sensors=SENSORS, sigma=SIGMA,
        q=Q_SPECTRAL, **opts):
    """Run a core filter over zs (K, m): predict(DT) then update each step. Returns the
    posterior means (K, 4), covariances (K, 4, 4) and the filter object."""
    motion, meas = models(sensors, sigma, q)
    f = make_filter(kind, motion, meas, np.array(x0, float), np.array(P0_, float), **opts)
    xs = np.empty((len(zs), 4))
    Ps = np.empty((len(zs), 4, 4))
    for k, z in enumerate(zs):
        f.step(DT, z)
        xs[k] = f.x
        Ps[k] = f.P
    return xs, Ps, f


def crossing_truth(steps: int = 200) -> np.ndarray:
    """A target moving straight down x = 0 from (0, 1) at speed 1: it passes behind a sensor
    at (1, 0) at step 100 (that sensor's bearing crosses +-pi). States (K, 4)."""
    t = DT * np.arange(1, steps + 1)
    return np.stack([np.zeros_like(t), 1.0 - t, np.zeros_like(t), -np.ones_like(t)], axis=1)


CROSSING_SENSORS = np.array([[1.0, 0.0], [-1.0, -3.0]])   # bearing of sensor 0 crosses +-pi
REFERENCE_SENSORS = np.array([[-1.0, 0.0], [-1.0, -3.0]])  # mirrored: it crosses 0 instead
CROSSING_X0 = np.array([0.05, 1.05, 0.2, -0.8])
CROSSING_P0 = np.diag([0.1, 0.1, 1.0, 1.0])


def run_batch(kind: str, zs: np.ndarray, x0=M0_FILTER, P0_=P0, sensors=SENSORS, sigma=SIGMA,
              q=Q_SPECTRAL, **opts):
    """The same filter over R independent runs at once, zs (R, K, m) -> means (R, K, 4) and
    covariances (R, K, 4, 4). Used where hundreds of thousands of steps are needed (Monte
    Carlo); test_consistency checks that it reproduces the core filter objects (`run`).

    ekf: the core's own batched kf_predict / kf_update, with the core's Bearings.H per run.
    ukf / ckf: the core's SigmaPointRule (same points and weights), models' h and wrapped
    residuals, and the same equations as SigmaPointKalmanFilter, written over a batch axis;
    with linear dynamics the sigma-point prediction is exactly F P F' + Q (SEEDS 1.3)."""
    from vtrack.estimation.kalman import kf_predict, kf_update

    motion, meas = models(sensors, sigma, q)
    f0 = make_filter(kind, motion, meas, np.array(x0, float), np.array(P0_, float), **opts)
    F, Q = motion.transition(DT), motion.Q(DT)
    R_runs, K, m = zs.shape
    x = np.broadcast_to(np.asarray(x0, float), (R_runs, 4)).copy()
    P = np.broadcast_to(np.asarray(P0_, float), (R_runs, 4, 4)).copy()
    xs = np.empty((R_runs, K, 4))
    Ps = np.empty((R_runs, K, 4, 4))
    T = lambda a: np.swapaxes(a, -1, -2)  # noqa: E731
    for k in range(K):
        x, P = kf_predict(x, P, np.broadcast_to(F, P.shape), Q)
        if kind == "ekf":
            H = np.stack([meas.H(xr) for xr in x])
            nu = meas.residual(zs[:, k], meas.h(x))
            x, P, _ = kf_update(x, P, nu, H, meas.R)
        else:
            rule = f0.rule
            L = np.linalg.cholesky(P)
            cols = rule.spread * T(L)                                   # (R, n, n) rows = L_i
            pts = [x[:, None, :]] if rule.center else []
            X = np.concatenate(pts + [x[:, None, :] + cols, x[:, None, :] - cols], axis=1)
            ref = meas.h(x)[:, None, :]
            ybar = ref[:, 0] + np.einsum("i,rim->rm", rule.Wm, meas.residual(meas.h(X), ref))
            dY = meas.residual(meas.h(X), ybar[:, None, :])
            dX = X - x[:, None, :]
            S = np.einsum("i,rim,rin->rmn", rule.Wc, dY, dY) + meas.R
            Pxy = np.einsum("i,rim,rin->rmn", rule.Wc, dX, dY)
            Kg = T(np.linalg.solve(S, T(Pxy)))
            nu = meas.residual(zs[:, k], ybar)
            x = x + np.einsum("rij,rj->ri", Kg, nu)
            P = P - Kg @ S @ T(Kg)
            P = 0.5 * (P + T(P))
        xs[:, k] = x
        Ps[:, k] = P
    return xs, Ps
