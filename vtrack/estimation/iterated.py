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

Everything here takes a stack of runs (a leading axis: x (R, n), P (R, n, n), z (R, m)) or
one track (no leading axis). Each run keeps its own damping, step acceptance and iteration
count (masks over the leading axis); a run that has settled takes no further part.
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


def _mv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A v over stacks: (..., a, b) x (..., b) -> (..., a)."""
    return (A @ v[..., None])[..., 0]


def _solve_vec(L: np.ndarray, v: np.ndarray) -> np.ndarray:
    """L^-1 v over stacks: (..., a, a), (..., a) -> (..., a)."""
    return np.linalg.solve(L, v[..., None])[..., 0]


def _sq(v: np.ndarray) -> np.ndarray:
    return np.sum(v * v, axis=-1)


def damped_step(motion: MotionModel, x_prior: np.ndarray, P_prior: np.ndarray, m: np.ndarray,
                r: np.ndarray, A: np.ndarray, Rk: np.ndarray, mu: np.ndarray | float
                ) -> np.ndarray:
    """The Levenberg-Marquardt step of the module docstring from the iterate m, where
    r = wrap(z - y): the mean of kf_update(x~, P-/(1+mu), r + A (m - x~), A, Rk) with
    x~ = x- + mu/(1+mu) (m - x-). mu = 0 gives the Gauss-Newton step; mu (...,) per run."""
    mu = np.asarray(mu, dtype=float)
    x_tilde = x_prior + (mu / (1.0 + mu))[..., None] * motion.residual(m, x_prior)
    x, _, _ = kf_update(x_tilde, P_prior / (1.0 + mu)[..., None, None],
                        r + _mv(A, motion.residual(m, x_tilde)), A, Rk)
    return x


def linearised_cost(motion: MotionModel, x_prior: np.ndarray, Lp: np.ndarray, m: np.ndarray,
                    r: np.ndarray, A: np.ndarray, Lr: np.ndarray, x: np.ndarray) -> np.ndarray:
    """|x - x-|^2_{P-} + |r - A (x - m)|^2_{Rk}: the cost with h linearised about m
    (Lp, Lr: Cholesky factors of P- and Rk); one value per run (...,)."""
    a = _solve_vec(Lp, motion.residual(x, x_prior))
    b = _solve_vec(Lr, r - _mv(A, motion.residual(x, m)))
    return _sq(a) + _sq(b)


def merit(motion: MotionModel, meas: MeasurementModel, x_prior: np.ndarray, Lp: np.ndarray,
          z: np.ndarray, R: np.ndarray, x: np.ndarray, lin: Linearisation) -> np.ndarray:
    """The cost a damped step must lower, for the linearisation lin = (A, y, Omega) about x:

        V(x) = |x - x-|^2_{P-} + |wrap(z - y)|^2_{R~} + log det(A P- A' + R~),  R~ = R + Omega

    -2 log of the Laplace approximation of the posterior probability mass at x (Tierney &
    Kadane 1986): the density N(x; x-, P-) N(z; y, R~) times the volume det(2 pi P(x))^1/2 of
    the posterior Gaussian there, P(x)^-1 = P-^-1 + A' R~^-1 A (matrix determinant lemma:
    det(R~) det(I + L-' A' R~^-1 A L-) = det(A P- A' + R~)), constants dropped. Without the
    log det it is the MAP cost, which a bearing makes arbitrarily low next to its sensor, where
    any bearing is matched by a tiny move and the posterior holds no mass; the log det, which
    grows like 2 log(1/range) there, keeps the iterations out of that spike. Lp: Cholesky
    factor of P-. One value per run (...,)."""
    A, y, Omega = lin
    Rk = R if Omega is None else R + Omega
    a = _solve_vec(Lp, motion.residual(x, x_prior))
    b = _solve_vec(cholesky(Rk, "R + Omega"), meas.residual(z, y))
    ALp = A @ Lp
    S = cholesky(ALp @ np.swapaxes(ALp, -1, -2) + Rk, "innovation covariance S")
    logdet = np.sum(np.log(np.diagonal(S, axis1=-2, axis2=-1)), axis=-1)
    return _sq(a) + _sq(b) + 2.0 * logdet


class _Linearisations:
    """Per run, the current linearisation and the Kalman update it gives (the cache that a
    rejected step reuses): A, r = wrap(z - y), Rk = R + Omega, its factor Lr, the
    Gauss-Newton mean, the updated covariance, the innovation and the merit at the iterate."""

    def __init__(self, runs: int, n: int, m: int) -> None:
        self.A = np.empty((runs, m, n))
        self.r = np.empty((runs, m))
        self.Rk = np.empty((runs, m, m))
        self.Lr = np.empty((runs, m, m))
        self.x_gn = np.empty((runs, n))
        self.P = np.empty((runs, n, n))
        self.merit = np.zeros(runs)
        self.innovation = _Innovations(runs, n, m)


class _Innovations:
    """Per run, the innovation of an update (nu, S, K, NIS)."""

    def __init__(self, runs: int, n: int, m: int) -> None:
        self.nu = np.empty((runs, m))
        self.S = np.empty((runs, m, m))
        self.K = np.empty((runs, n, m))
        self.nis = np.empty(runs)

    def put(self, idx: np.ndarray, info: Innovation | _Innovations,
            src: np.ndarray | slice = slice(None)) -> None:
        """Set runs idx to the runs src of info."""
        self.nu[idx], self.S[idx] = info.nu[src], info.S[src]
        self.K[idx], self.nis[idx] = info.K[src], info.nis[src]

    def as_innovation(self) -> Innovation:
        return Innovation(nu=self.nu, S=self.S, K=self.K, nis=self.nis)


class _LinearisationsAhead:
    """For a linearisation that does not depend on the covariance (iekf: A = H(x), y = h(x)),
    the linearisation and merit computed by the acceptance test at an accepted step are those
    of the next iterate: kept here per run instead of being computed again."""

    def __init__(self, runs: int, n: int, m: int) -> None:
        self.A = np.empty((runs, m, n))
        self.y = np.empty((runs, m))
        self.Omega: np.ndarray | None = None
        self.merit = np.empty(runs)
        self.known = np.zeros(runs, dtype=bool)

    def keep(self, idx: np.ndarray, lin: Linearisation, merit: np.ndarray) -> None:
        A, y, Omega = lin
        self.A[idx], self.y[idx], self.merit[idx], self.known[idx] = A, y, merit, True
        if Omega is not None:
            if self.Omega is None:
                self.Omega = np.zeros((len(self.known),) + Omega.shape[-2:])
            self.Omega[idx] = Omega

    def take(self, idx: np.ndarray) -> tuple[Linearisation, np.ndarray]:
        self.known[idx] = False
        Omega = None if self.Omega is None else self.Omega[idx]
        return (self.A[idx], self.y[idx], Omega), self.merit[idx]


def iterated_update(motion: MotionModel, meas: MeasurementModel, x_prior: np.ndarray,
                    P_prior: np.ndarray, z: np.ndarray, R: np.ndarray,
                    linearise: Callable[[np.ndarray, np.ndarray], Linearisation],
                    max_iterations: int, tolerance: float, damped: bool = False,
                    uses_covariance: bool = True
                    ) -> tuple[np.ndarray, np.ndarray, Innovation, np.ndarray | int]:
    """The update of the prior (x-, P-) relinearised at its own result until it settles.

    From (m_0, P_0) = (x-, P-): linearise h about the current iterate, h(x) ~ y_i + A_i (x -
    m_i) with error covariance Omega_i (`linearise(m_i, P_i)`, called with a stack of
    iterates), and update the PRIOR with that linear model (Joseph form, kalman.kf_update):

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
    uses_covariance False declares that `linearise` ignores P (iekf): the linearisation and
    merit of an accepted step's test then serve its next iteration.

    x_prior (R, n), P_prior (R, n, n), z (R, m) and R ((R,) m, m) update R runs at once, each
    with its own damping, acceptance and count; without the leading axis, one track.
    Returns (x, P, innovation, iterations done: (R,), or an int for one track).
    """
    if np.ndim(x_prior) == 1:       # one track: a stack of one, h still sees one state
        def linearise_one(m: np.ndarray, P: np.ndarray) -> Linearisation:
            A, y, Omega = linearise(m[0], P[0])
            return A[None], np.asarray(y)[None], None if Omega is None else Omega[None]

        x, P, info, its = iterated_update(
            motion, meas, x_prior[None], P_prior[None], np.asarray(z)[None], R,
            linearise_one, max_iterations, tolerance, damped, uses_covariance)
        return x[0], P[0], Innovation(info.nu[0], info.S[0], info.K[0], info.nis[0]), int(its[0])
    it = _Iterations(motion, meas, x_prior, P_prior, z, R, linearise, damped, uses_covariance)
    runs = len(x_prior)
    iterations = np.zeros(runs, dtype=int)
    active = np.ones(runs, dtype=bool)
    stale = np.ones(runs, dtype=bool)                 # the iterate needs a linearisation
    accepted = np.zeros(runs, dtype=bool)
    while active.any():
        iterations[active] += 1
        new = np.flatnonzero(active & stale)
        if new.size:
            it.linearise_at(new)
            stale[new] = False
        act = np.flatnonzero(active)
        x = it.step(act)
        d = motion.residual(x, it.m[act])
        settled = np.sum(d * _solve_vec(it.lin.P[act], d), axis=-1) <= tolerance**2
        keep = np.ones(len(act), dtype=bool)
        if damped and not settled.all():
            keep[~settled] = it.test(act[~settled], x[~settled])
        ok = act[keep]
        it.m[ok], it.P[ok], accepted[ok], stale[ok] = x[keep], it.lin.P[ok], True, True
        it.accepted.put(ok, it.lin.innovation, ok)
        done = (iterations[act] >= max_iterations) | (keep & settled & (iterations[act] > 1))
        active[act[done]] = False
    never = np.flatnonzero(~accepted)   # no step was accepted: the prior stands, with the
    it.P[never] = it.lin.P[never]       # first update's P and innovation
    it.accepted.put(never, it.lin.innovation, never)
    return it.m, it.P, it.accepted.as_innovation(), iterations


def _per_iterate(linearise: Callable[[np.ndarray, np.ndarray], Linearisation]
                 ) -> Callable[[np.ndarray, np.ndarray], Linearisation]:
    """`linearise` with its (A, y, Omega) given for each iterate of the stack (a model with
    a constant Jacobian returns one A for all)."""
    def stacked(m: np.ndarray, P: np.ndarray) -> Linearisation:
        A, y, Omega = linearise(m, P)
        k = len(m)
        return (np.broadcast_to(A, (k,) + np.shape(A)[-2:]),
                np.broadcast_to(y, (k,) + np.shape(y)[-1:]),
                None if Omega is None else np.broadcast_to(Omega, (k,) + np.shape(Omega)[-2:]))

    return stacked


class _Iterations:
    """The state of the iterations of a stack of runs (iterated_update): the prior and its
    factor, the iterates m and covariances P, each run's damping mu and its growth, the
    current linearisations and the innovations of the accepted iterates."""

    def __init__(self, motion: MotionModel, meas: MeasurementModel, x_prior: np.ndarray,
                 P_prior: np.ndarray, z: np.ndarray, R: np.ndarray,
                 linearise: Callable[[np.ndarray, np.ndarray], Linearisation], damped: bool,
                 uses_covariance: bool) -> None:
        runs, n = x_prior.shape
        m = np.shape(R)[-1]
        self.motion, self.meas, self.damped = motion, meas, damped
        self.linearise = _per_iterate(linearise)
        self.x_prior, self.P_prior, self.z = x_prior, P_prior, z
        self.R = np.broadcast_to(R, (runs, m, m))
        self.Lp = cholesky(P_prior, "predicted covariance")
        self.m, self.P = x_prior.copy(), P_prior.copy()
        self.mu, self.grow = np.zeros(runs), np.full(runs, 2.0)
        self.lin = _Linearisations(runs, n, m)
        self.accepted = _Innovations(runs, n, m)
        self.ahead = None if uses_covariance else _LinearisationsAhead(runs, n, m)

    def linearise_at(self, idx: np.ndarray) -> None:
        """Linearise h about the iterates m[idx] and store the Gauss-Newton update of the
        prior with it (and the merit at the iterates when damped) in `lin` at idx."""
        lin, m = self.lin, self.m[idx]
        xp, zi, Ri = self.x_prior[idx], self.z[idx], self.R[idx]
        if self.ahead is not None and self.ahead.known[idx].all():
            here, v_m = self.ahead.take(idx)
        else:                       # (recomputing a kept one gives the same numbers)
            if self.ahead is not None:
                self.ahead.known[idx] = False
            here = self.linearise(m, self.P[idx])
            v_m = merit(self.motion, self.meas, xp, self.Lp[idx], zi, Ri, m, here) \
                if self.damped else 0.0
        A, y, Omega = here
        Rk = Ri if Omega is None else Ri + Omega
        r = self.meas.residual(zi, y)
        x_gn, P_new, inn = kf_update(xp, self.P_prior[idx],
                                     r + _mv(A, self.motion.residual(m, xp)), A, Rk)
        lin.merit[idx] = v_m
        lin.Lr[idx] = cholesky(Rk, "measurement noise R")
        lin.A[idx], lin.r[idx], lin.Rk[idx], lin.x_gn[idx], lin.P[idx] = A, r, Rk, x_gn, P_new
        lin.innovation.put(idx, inn)

    def step(self, idx: np.ndarray) -> np.ndarray:
        """The next step of runs idx: the Gauss-Newton mean, or the damped step where mu > 0."""
        lin = self.lin
        x = lin.x_gn[idx]
        lm = self.mu[idx] != 0.0
        if lm.any():
            d = idx[lm]
            x[lm] = damped_step(self.motion, self.x_prior[d], self.P_prior[d], self.m[d],
                                lin.r[d], lin.A[d], lin.Rk[d], self.mu[d])
        return x

    def test(self, idx: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The damped acceptance test of the steps x of runs idx: keep a step iff it lowers
        the merit; adapt each run's damping mu (the module docstring: the gain ratio rho for
        a kept step, 0.1 (1 + |R^-1/2 A L-|^2) or x nu, nu doubling, for a rejected one).
        Returns the mask of the kept steps."""
        lin, mu, grow, Lp = self.lin, self.mu, self.grow, self.Lp
        at_x = self.linearise(x, self.P[idx])
        v_x = merit(self.motion, self.meas, self.x_prior[idx], Lp[idx], self.z[idx],
                    self.R[idx], x, at_x)
        keep = v_x < lin.merit[idx]
        rej = idx[~keep]
        if rej.size:
            undamped = mu[rej] == 0.0
            first, again = rej[undamped], rej[~undamped]
            if first.size:
                J = np.linalg.solve(lin.Lr[first], lin.A[first] @ Lp[first])
                mu[first] = 0.1 * (1.0 + np.linalg.norm(J, 2, axis=(-2, -1)) ** 2)
            mu[again] *= grow[again]
            grow[rej] *= 2.0
        acc = idx[keep]
        if acc.size:
            m = self.m[acc]
            args = (self.motion, self.x_prior[acc], Lp[acc], m, lin.r[acc], lin.A[acc],
                    lin.Lr[acc])
            predicted = linearised_cost(*args, m) - linearised_cost(*args, x[keep])
            with np.errstate(divide="ignore", invalid="ignore"):
                rho = np.where(predicted > 0.0, (lin.merit[acc] - v_x[keep]) / predicted, 0.0)
            mu[acc] *= np.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            grow[acc] = 2.0
            if self.ahead is not None:
                A, y, Omega = at_x
                self.ahead.keep(acc, (A[keep], y[keep], None if Omega is None else Omega[keep]),
                                v_x[keep])
        return keep
