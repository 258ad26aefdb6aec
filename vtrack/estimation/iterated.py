"""The iterated measurement update shared by the iterated EKF (filters.py) and the iterated
posterior linearisation filter (sigma_filters.py): Gauss-Newton steps relinearised at their
own result, damped by Levenberg-Marquardt on a cost (the MAP cost for iekf).

Damping (Levenberg 1944, Marquardt 1963; the LM-IEKF of Skoglund, Hendeby & Axehill 2015,
"Extended Kalman filter modifications based on an optimization view point", FUSION):
iteration i minimises the linearised cost plus mu_i |x - m_i|^2_{P-} (the damping measured
in the prior's metric, so it does not depend on the state's units). That is the Kalman
update of a pseudo-prior, so the step keeps the Kalman form:

    x~ = x- + mu/(1+mu) (m_i - x-),   P~ = P- / (1+mu)
    m_{i+1} = kf_update(x~, P~, wrap(z - y_i) + A_i (m_i - x~), A_i, R + Omega_i)

mu = 0 is the plain Gauss-Newton step. mu starts at 0, so the first step is the EKF (or
UKF/CKF) update; a step that does not lower the cost is rejected and retried with a larger mu
(0.1 (1 + |R^-1/2 A L-|^2), then x nu, nu doubling); an accepted step scales mu by
max(1/3, 1 - (2 rho - 1)^3), rho = actual / predicted decrease of the cost (the gain ratio;
Nielsen 1999, Madsen, Nielsen & Tingleff 2004, eq. 2.21). Every iterate therefore has a
lower cost than the one before.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vtrack.estimation.kalman import Innovation, kf_update
from vtrack.estimation.linalg import cholesky
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.options import bool_option, float_option, int_option

Linearisation = tuple[np.ndarray, np.ndarray, np.ndarray | None]
"""h(x) ~ y + A (x - m) about a point m, with error covariance Omega (None: zero)."""

MAX_ITERATIONS = 30     # defaults of the iterated kinds (iekf, iplf); see docs/EXPERIMENTS.md
TOLERANCE = 1e-4
DAMPED = True


def iteration_options(max_iterations: object, tolerance: object, damped: object = DAMPED
                      ) -> tuple[int, float, bool]:
    """Validated (max_iterations: integer >= 1, tolerance: number > 0, damped: flag) of an
    iterated kind."""
    return (int_option("max_iterations", max_iterations, 1),
            float_option("tolerance", tolerance, 0.0), bool_option("damped", damped))


def damped_step(motion: MotionModel, x_prior: np.ndarray, P_prior: np.ndarray, m: np.ndarray,
                r: np.ndarray, A: np.ndarray, Rk: np.ndarray, mu: float) -> np.ndarray:
    """The Levenberg-Marquardt step of the module docstring from the iterate m, where
    r = wrap(z - y): the mean of kf_update(x~, P-/(1+mu), r + A (m - x~), A, Rk) with
    x~ = x- + mu/(1+mu) (m - x-). mu = 0 gives the Gauss-Newton step."""
    x_tilde = x_prior + (mu / (1.0 + mu)) * motion.residual(m, x_prior)
    x, _, _ = kf_update(x_tilde, P_prior / (1.0 + mu), r + A @ motion.residual(m, x_tilde), A, Rk)
    return x


def linearised_cost(motion: MotionModel, x_prior: np.ndarray, Lp: np.ndarray, m: np.ndarray,
                    r: np.ndarray, A: np.ndarray, Lr: np.ndarray, x: np.ndarray) -> float:
    """|x - x-|^2_{P-} + |r - A (x - m)|^2_{Rk}: the cost with h linearised about m
    (Lp, Lr: Cholesky factors of P- and Rk)."""
    a = np.linalg.solve(Lp, motion.residual(x, x_prior))
    b = np.linalg.solve(Lr, r - A @ motion.residual(x, m))
    return float(a @ a + b @ b)


def merit(motion: MotionModel, meas: MeasurementModel, x_prior: np.ndarray, Lp: np.ndarray,
          z: np.ndarray, R: np.ndarray, x: np.ndarray, lin: Linearisation) -> float:
    """The cost a damped step must lower, for the linearisation lin = (A, y, Omega) about x:

        V(x) = |x - x-|^2_{P-} + |wrap(z - y)|^2_{R~} + log det(A P- A' + R~),  R~ = R + Omega

    -2 log of the Laplace approximation of the posterior probability mass at x (Tierney &
    Kadane 1986): the density N(x; x-, P-) N(z; y, R~) times the volume det(2 pi P(x))^1/2 of
    the posterior Gaussian there, P(x)^-1 = P-^-1 + A' R~^-1 A (matrix determinant lemma:
    det(R~) det(I + L-' A' R~^-1 A L-) = det(A P- A' + R~)), constants dropped. Without the
    log det it is the MAP cost, which a bearing makes arbitrarily low next to its sensor, where
    any bearing is matched by a tiny move and the posterior holds no mass; the log det, which
    grows like 2 log(1/range) there, keeps the iterations out of that spike. Lp: Cholesky
    factor of P-."""
    A, y, Omega = lin
    Rk = R if Omega is None else R + Omega
    a = np.linalg.solve(Lp, motion.residual(x, x_prior))
    b = np.linalg.solve(cholesky(Rk, "R + Omega"), meas.residual(z, y))
    S = cholesky(A @ Lp @ (A @ Lp).T + Rk, "innovation covariance S")
    return float(a @ a + b @ b + 2.0 * np.sum(np.log(np.diag(S))))


def iterated_update(motion: MotionModel, meas: MeasurementModel, x_prior: np.ndarray,
                    P_prior: np.ndarray, z: np.ndarray, R: np.ndarray,
                    linearise: Callable[[np.ndarray, np.ndarray], Linearisation],
                    max_iterations: int, tolerance: float, damped: bool = False
                    ) -> tuple[np.ndarray, np.ndarray, Innovation, int]:
    """The update of the prior (x-, P-) relinearised at its own result until it settles.

    From (m_0, P_0) = (x-, P-): linearise h about the current iterate, h(x) ~ y_i + A_i (x -
    m_i) with error covariance Omega_i (`linearise(m_i, P_i)`), and update the PRIOR with that
    linear model (Joseph form, kalman.kf_update):

        nu_i = wrap(z - y_i) + A_i (m_i - x-)        (= z - [y_i + A_i (x- - m_i)])
        P_{i+1}, innovation = kf_update(x-, P-, nu_i, A_i, R + Omega_i)

    Undamped, the new mean is that update's (plain Gauss-Newton). Damped, the mean takes the
    Levenberg-Marquardt step of the module docstring (damped_step) and a step x is kept only
    if it lowers the merit V (merit(), with the linearisation about x, covariance P_i);
    a rejected step is retried with more damping at the same linearisation. Every step tried
    counts as an iteration. A step that is small in the new posterior's metric,
    sqrt(d' P_{i+1}^-1 d) <= tolerance (angles wrapped), is taken without the test and,
    after the first iteration, ends the iterations; so do max_iterations. The covariance and
    innovation returned are those of the linearisation that produced the returned mean.
    Returns (x, P, innovation, iterations done).
    """
    m, P = x_prior, P_prior
    Lp = cholesky(P_prior, "predicted covariance")
    mu, grow = 0.0, 2.0
    lin = None
    info: Innovation | None = None
    i = 0
    while i < max_iterations:
        i += 1
        if lin is None:
            A, y, Omega = here = linearise(m, P)
            Rk = R if Omega is None else R + Omega
            r = meas.residual(z, y)
            x_gn, P_new, info_new = kf_update(x_prior, P_prior, r + A @ motion.residual(m, x_prior),
                                              A, Rk)
            v_m = merit(motion, meas, x_prior, Lp, z, R, m, here) if damped else 0.0
            Lr = cholesky(Rk, "measurement noise R")
            lin = (A, r, Rk, Lr, x_gn, P_new, info_new, v_m)
        A, r, Rk, Lr, x_gn, P_new, info_new, v_m = lin
        x = x_gn if mu == 0.0 else damped_step(motion, x_prior, P_prior, m, r, A, Rk, mu)
        d = motion.residual(x, m)
        settled = float(d @ np.linalg.solve(P_new, d)) <= tolerance**2
        if damped and not settled:
            v_x = merit(motion, meas, x_prior, Lp, z, R, x, linearise(x, P))
            if not v_x < v_m:                       # reject: damp more, same linearisation
                if mu == 0.0:
                    J = np.linalg.solve(Lr, A @ Lp)
                    mu = 0.1 * (1.0 + float(np.linalg.norm(J, 2)) ** 2)
                else:
                    mu *= grow
                grow *= 2.0
                continue
            predicted = (linearised_cost(motion, x_prior, Lp, m, r, A, Lr, m)
                         - linearised_cost(motion, x_prior, Lp, m, r, A, Lr, x))
            rho = (v_m - v_x) / predicted if predicted > 0.0 else 0.0
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            grow = 2.0
        m, P, info, lin = x, P_new, info_new, None
        if i > 1 and settled:
            break
    if info is None:            # no step was accepted: the prior stands, with the first update's P
        P, info = lin[5], lin[6]
    return m, P, info, i
