"""Motion and measurement models. Each owns f/h, its Jacobian, Q/R and its residual.

State vectors are 1-D arrays; every f/h also accepts a stack of states (..., n), which is
how sigma points and batched tracks are propagated. Angular components are listed in
`angles` so residuals wrap them to (-pi, pi] (SEEDS 1.4).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vtrack.estimation.linalg import wrap_angle


def _residual(a: np.ndarray, b: np.ndarray, angles: tuple[int, ...]) -> np.ndarray:
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if angles and len(angles) == d.shape[-1]:       # every component an angle (bearings)
        return wrap_angle(d)
    if angles:
        idx = list(angles)
        d[..., idx] = wrap_angle(d[..., idx])
    return d


# ----------------------------------------------------------------------------- motion


class MotionModel:
    """x_k = f(x_{k-1}, dt, u) + w,  w ~ N(0, Q(dt))."""

    n: int
    angles: tuple[int, ...] = ()
    linear: bool = False
    names: tuple[str, ...] = ()

    def f(self, x: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
        raise NotImplementedError

    def F(self, x: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
        """Jacobian df/dx at x."""
        raise NotImplementedError

    def Q(self, dt: float) -> np.ndarray:
        raise NotImplementedError

    def residual(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """a - b with angular states wrapped."""
        return _residual(a, b, self.angles)


class LinearMotion(MotionModel):
    """Linear-Gaussian motion x_k = Phi(dt) x_{k-1} + w built per axis: Phi = kron(Phi_axis, I_d).

    Phi(dt) and Q(dt) / q are kept per dt, read-only (a video's frame spacings, a Monte Carlo
    loop's step, take a few values; at most DISCRETE_KEPT are kept)."""

    linear = True
    DISCRETE_KEPT = 32

    def __init__(self, q: float, dim: int = 2) -> None:
        self.q = float(q)
        self.dim = dim
        self._discrete: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def _axis(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _kept(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi(dt), Q(dt) / q), read-only."""
        kept = self._discrete.get(dt)
        if kept is None:
            eye = np.eye(self.dim)
            kept = tuple(np.kron(a, eye) for a in self._axis(dt))
            for a in kept:
                a.flags.writeable = False
            if len(self._discrete) >= self.DISCRETE_KEPT:
                self._discrete.clear()
            self._discrete[dt] = kept
        return kept

    def transition(self, dt: float) -> np.ndarray:
        """Phi(dt), read-only."""
        return self._kept(dt)[0]

    def f(self, x: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
        return np.asarray(x, dtype=float) @ self.transition(dt).T

    def F(self, x: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
        return self.transition(dt)

    def Q(self, dt: float) -> np.ndarray:
        return self.q * self._kept(dt)[1]


class WienerVelocity(LinearMotion):
    """Nearly-constant velocity, state [x, y, vx, vy]; Q of seed 000 eq. (3) (toolbox lti_disc)."""

    def __init__(self, q: float, dim: int = 2) -> None:
        super().__init__(q, dim)
        self.n = 2 * dim
        self.names = ("x", "y", "vx", "vy")[: self.n] if dim == 2 else ()

    def _axis(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        phi = np.array([[1.0, dt], [0.0, 1.0]])
        q = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        return phi, q


class ConstantAcceleration(LinearMotion):
    """State [x, y, vx, vy, ax, ay]; Phi of seed 001 eq. (22), white-jerk Q (SEEDS 3.1)."""

    def __init__(self, q: float, dim: int = 2) -> None:
        super().__init__(q, dim)
        self.n = 3 * dim
        self.names = ("x", "y", "vx", "vy", "ax", "ay") if dim == 2 else ()

    def _axis(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        phi = np.array([[1.0, dt, dt**2 / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        q = np.array(
            [
                [dt**5 / 20, dt**4 / 8, dt**3 / 6],
                [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                [dt**3 / 6, dt**2 / 2, dt],
            ]
        )
        return phi, q


def singer_transition(dt: float, alpha: float, dim: int = 2) -> np.ndarray:
    """Phi(dt) over [x, y, vx, vy, ax, ay] of an acceleration that is a first-order Markov
    process, a' = -alpha a + w, alpha the reciprocal of its time constant in 1/s (Singer
    1970, IEEE TAES 6(4); Li & Jilkov 2003, "Survey of maneuvering target tracking, Part I",
    sec. 4.1); per axis, with r = exp(-alpha dt):

        [[1, dt, (alpha dt - 1 + r) / alpha^2],
         [0, 1,  (1 - r) / alpha],
         [0, 0,  r]]

    alpha = 0 is the constant acceleration of seed 001 eq. (22) (its limit), alpha = inf
    drops the acceleration (constant velocity)."""
    if alpha == 0:
        return ConstantAcceleration(1.0, dim).transition(dt)
    phi = np.array([[1.0, dt, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    if np.isfinite(alpha):
        e = np.expm1(-alpha * dt)          # r - 1, exact where alpha dt is small
        phi[0, 2] = (alpha * dt + e) / alpha**2
        phi[1, 2] = -e / alpha
        phi[2, 2] = 1.0 + e
    return np.kron(phi, np.eye(dim))


class Unicycle(MotionModel):
    """Robot pose [x, y, heading] driven by u = (speed, turn rate); seed 002 eq. (1) form.

    theta' = theta + omega dt;  x' = x + v dt cos(theta');  y' = y + v dt sin(theta').
    Q = diag(q) dt (q: spectral density per state; a number applies to all three).
    """

    n = 3
    angles = (2,)
    names = ("x", "y", "heading")

    def __init__(self, q: float | np.ndarray) -> None:
        self.q = np.broadcast_to(np.asarray(q, dtype=float), (3,)).copy()

    @staticmethod
    def _u(u: np.ndarray | None) -> tuple[np.ndarray | float, np.ndarray | float]:
        """(speed, turn rate): numbers, or one per run (...,) for a stack of inputs."""
        if u is None:
            return 0.0, 0.0
        u = np.asarray(u, dtype=float)
        return u[..., 0], u[..., 1]

    def f(self, x: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
        v, om = self._u(u)
        x = np.asarray(x, dtype=float)
        out = np.array(x, copy=True)
        th = x[..., 2] + om * dt
        out[..., 0] = x[..., 0] + v * dt * np.cos(th)
        out[..., 1] = x[..., 1] + v * dt * np.sin(th)
        out[..., 2] = th
        return out

    def F(self, x: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
        v, om = self._u(u)
        th = np.asarray(x, dtype=float)[..., 2] + om * dt
        J = np.broadcast_to(np.eye(3), np.shape(th) + (3, 3)).copy()
        J[..., 0, 2] = -v * dt * np.sin(th)
        J[..., 1, 2] = v * dt * np.cos(th)
        return J

    def Q(self, dt: float) -> np.ndarray:
        return np.diag(self.q * dt)


# ------------------------------------------------------------------------ measurement


class MeasurementModel:
    """z = h(x) + v,  v ~ N(0, R)."""

    m: int
    R: np.ndarray
    angles: tuple[int, ...] = ()
    linear: bool = False

    def h(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def H(self, x: np.ndarray) -> np.ndarray:
        """Jacobian dh/dx at x."""
        raise NotImplementedError

    def residual(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """a - b with angular components wrapped to (-pi, pi]."""
        return _residual(a, b, self.angles)

    def row_indices(self) -> np.ndarray:
        """Indices of the rows of the full measurement vector this model holds (all here; the
        present rows for a model restricted by `subset`)."""
        return np.arange(self.m)

    def subset(self, rows: np.ndarray) -> "MeasurementModel":
        """The model restricted to the measurement rows present (missing cells dropped)."""
        rows = np.asarray(rows)
        if rows.dtype == bool:
            rows = np.flatnonzero(rows)
        if len(rows) == self.m:
            return self
        return _Subset(self, rows)


def _noise_cov(sigma: float | np.ndarray, m: int) -> np.ndarray:
    s = np.broadcast_to(np.asarray(sigma, dtype=float), (m,))
    return np.diag(s**2)


class LinearMeasurement(MeasurementModel):
    """z = H x + v (seed 001 eq. 25 with H = I6; 'position' picks the position)."""

    linear = True

    def __init__(self, H: np.ndarray, R: np.ndarray, angles: tuple[int, ...] = ()) -> None:
        self._H = np.atleast_2d(np.asarray(H, dtype=float))
        self.m = self._H.shape[0]
        self.R = np.asarray(R, dtype=float)
        self.angles = angles

    def h(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=float) @ self._H.T

    def H(self, x: np.ndarray) -> np.ndarray:
        return self._H


def position_measurement(n: int, sigma: float | np.ndarray, dim: int = 2) -> LinearMeasurement:
    """Linear measurement of the first `dim` state components (the position)."""
    H = np.zeros((dim, n))
    H[:, :dim] = np.eye(dim)
    return LinearMeasurement(H, _noise_cov(sigma, dim))


def pose_measurement(sigma: float | np.ndarray) -> LinearMeasurement:
    """Pose z = [x, y, heading] + v of a unicycle state; the heading residual wraps (SEEDS 4.3)."""
    return LinearMeasurement(np.eye(3), _noise_cov(sigma, 3), angles=(2,))


def _position_jacobian(d_dx: np.ndarray, d_dy: np.ndarray, n: int) -> np.ndarray:
    """Jacobian rows (..., m, n) of a measurement of the position: d/dx, d/dy in columns 0
    and 1, zeros elsewhere (a stack of states gives a stack of Jacobians)."""
    J = np.zeros(d_dx.shape + (n,))
    J[..., 0] = d_dx
    J[..., 1] = d_dy
    return J


class Bearings(MeasurementModel):
    """One bearing per sensor, h_i = atan2(y - sy_i, x - sx_i) (seed 000 eq. 4, with atan2).

    Jacobian row [-(y - sy)/r^2, +(x - sx)/r^2, 0, ...]: seed 000 eq. 8 prints the wrong sign
    on d/dy; the toolbox's bot_dh_dx.m has '+'.
    """

    def __init__(self, sensors: np.ndarray, sigma: float | np.ndarray, n: int = 4) -> None:
        self.sensors = np.atleast_2d(np.asarray(sensors, dtype=float))
        self.m = len(self.sensors)
        self.n = n
        self.R = _noise_cov(sigma, self.m)
        self.angles = tuple(range(self.m))

    def _d(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float)
        dx = x[..., None, 0] - self.sensors[:, 0]
        dy = x[..., None, 1] - self.sensors[:, 1]
        return dx, dy

    def h(self, x: np.ndarray) -> np.ndarray:
        dx, dy = self._d(x)
        return np.arctan2(dy, dx)

    def H(self, x: np.ndarray) -> np.ndarray:
        dx, dy = self._d(x)
        r2 = dx**2 + dy**2
        return _position_jacobian(-dy / r2, dx / r2, self.n)


class Ranges(MeasurementModel):
    """One range per sensor, h_i = ||p - s_i||; Jacobian row [dx/r, dy/r, 0, ...] (SEEDS 7.2)."""

    def __init__(self, sensors: np.ndarray, sigma: float | np.ndarray, n: int = 4) -> None:
        self.sensors = np.atleast_2d(np.asarray(sensors, dtype=float))
        self.m = len(self.sensors)
        self.n = n
        self.R = _noise_cov(sigma, self.m)

    def h(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        return np.hypot(x[..., None, 0] - self.sensors[:, 0], x[..., None, 1] - self.sensors[:, 1])

    def H(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        dx = x[..., None, 0] - self.sensors[:, 0]
        dy = x[..., None, 1] - self.sensors[:, 1]
        r = np.hypot(dx, dy)
        return _position_jacobian(dx / r, dy / r, self.n)


@dataclass
class _Subset(MeasurementModel):
    """Rows `rows` of another measurement model (used for missing measurement cells)."""

    base: MeasurementModel
    rows: np.ndarray
    m: int = field(init=False)
    R: np.ndarray = field(init=False)
    angles: tuple[int, ...] = field(init=False)

    def __post_init__(self) -> None:
        self.m = len(self.rows)
        self.R = self.base.R[np.ix_(self.rows, self.rows)]
        pos = {int(r): i for i, r in enumerate(self.rows)}
        self.angles = tuple(pos[a] for a in self.base.angles if a in pos)
        self.linear = self.base.linear

    def h(self, x: np.ndarray) -> np.ndarray:
        return self.base.h(x)[..., self.rows]

    def H(self, x: np.ndarray) -> np.ndarray:
        return self.base.H(x)[..., self.rows, :]

    def row_indices(self) -> np.ndarray:
        return np.asarray(self.rows)
