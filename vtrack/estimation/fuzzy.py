"""Fuzzy-adaptive filter kinds (fuzzy-r, fuzzy-q of seed 003; siim-ekf of seed 004).

All three are ExtendedKalmanFilter subclasses: the Kalman maths is the shared Joseph-form
step (vtrack.estimation.kalman); what is added here is only how Q and R change between steps.

* ``fuzzy-r`` / ``fuzzy-q`` (seed 003, SEEDS 5.3): per measurement axis j, the windowed
  "actual" innovation variance Sr_jj = (1/N) sum nu_j^2 is compared with the filter's
  theoretical S_jj = [H P- H' + R]_jj by the nine-rule Mamdani FIS of the paper's Table 1.
  The output changes R additively (R_jj += AdjR) or Q multiplicatively (Q *= AdjQ).
* ``siim-ekf`` (seed 004, SEEDS 6.2): a 2-input, 4-rule "simplified indirect inference"
  fuzzy system gives alpha in [-1, 1] from the relative covariance-trace drop and the
  relative residual; then Q <- (1 - gamma alpha) Q and R <- (1 + gamma alpha) R.

The adapted Q or R applies from the next step on (R_{k+1} = R_k + AdjR in the paper's
notation); the Joseph form keeps P valid with the resulting non-optimal gains.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from vtrack.estimation.filters import ExtendedKalmanFilter, register
from vtrack.estimation.kalman import Innovation, kf_predict
from vtrack.estimation.models import MeasurementModel, MotionModel

# ------------------------------------------------------------------ Mamdani inference


def gaussian_mf(u: np.ndarray, centre: float, sigma: float) -> np.ndarray:
    """Gaussian membership exp(-(u - centre)^2 / (2 sigma^2))."""
    return np.exp(-0.5 * ((np.asarray(u, dtype=float) - centre) / sigma) ** 2)


def triangular_mf(y: np.ndarray, a: float, b: float, c: float) -> np.ndarray:
    """Triangle with feet a, c and peak b (a == b or b == c gives a right-angled shoulder)."""
    y = np.asarray(y, dtype=float)
    left = np.ones_like(y) if b == a else (y - a) / (b - a)
    right = np.ones_like(y) if c == b else (c - y) / (c - b)
    out = np.minimum(left, right)
    out = np.where((y < a) | (y > c), 0.0, out)
    return np.clip(out, 0.0, 1.0)


@dataclass(frozen=True)
class Mamdani:
    """A Mamdani FIS: Gaussian input terms, triangular output terms on [lo, hi], rules as data.

    `rules` maps a tuple of input term names (one per input, in input order) to an output
    term name. Inference: AND = min, clipped consequents, max aggregation, centroid over
    `points` samples of the output universe (SEEDS 5.3). Evaluation is vectorised: each input
    may be an array (e.g. one value per measurement axis) and the output has their shape.
    Where no rule fires at all the output is the universe's midpoint ('maintain').
    """

    inputs: tuple[Mapping[str, tuple[float, float]], ...]   # per input: term -> (centre, sigma)
    outputs: Mapping[str, tuple[float, float, float]]        # term -> (a, b, c)
    rules: Mapping[tuple[str, ...], str]
    universe: tuple[float, float] = (-1.0, 1.0)
    points: int = 201

    def __post_init__(self) -> None:
        grid = np.linspace(self.universe[0], self.universe[1], self.points)
        object.__setattr__(self, "_grid", grid)
        object.__setattr__(self, "_out_mf", {name: triangular_mf(grid, *abc)
                                             for name, abc in self.outputs.items()})

    def __call__(self, *u: np.ndarray) -> np.ndarray:
        if len(u) != len(self.inputs):
            raise ValueError(f"FIS takes {len(self.inputs)} inputs, got {len(u)}")
        u = np.broadcast_arrays(*[np.asarray(v, dtype=float) for v in u])
        grid, out_mf = self._grid, self._out_mf  # type: ignore[attr-defined]
        mu = [{t: gaussian_mf(ui, *cs) for t, cs in terms.items()}
              for ui, terms in zip(u, self.inputs)]
        agg = np.zeros(u[0].shape + (self.points,))
        for antecedent, consequent in self.rules.items():
            w = mu[0][antecedent[0]]
            for i, term in enumerate(antecedent[1:], start=1):
                w = np.minimum(w, mu[i][term])
            agg = np.maximum(agg, np.minimum(w[..., None], out_mf[consequent]))
        mass = agg.sum(axis=-1)
        mid = 0.5 * (self.universe[0] + self.universe[1])
        with np.errstate(invalid="ignore", divide="ignore"):
            centroid = (agg * grid).sum(axis=-1) / mass
        return np.where(mass > 0.0, centroid, mid)


# Linguistic levels of seed 003's inputs, in increasing order (SEEDS 5.3: NS < ZE < L).
LEVELS: tuple[str, ...] = ("NS", "ZE", "L")

# Seed 003 Table 1: (Sr_k term, S_k term) -> action on R (rows Sr, columns S).
# M = maintain, I = increase, D = decrease. Read with NS < ZE < L this is one principle:
# S above Sr (the filter expects more innovation than it sees) -> decrease; below -> increase.
HAMID_RULES: dict[tuple[str, str], str] = {
    ("ZE", "ZE"): "M", ("ZE", "NS"): "I", ("ZE", "L"): "D",
    ("NS", "ZE"): "D", ("NS", "NS"): "M", ("NS", "L"): "D",
    ("L", "ZE"): "I", ("L", "NS"): "I", ("L", "L"): "M",
}

# [A] Gaussian input terms on u = log10(S_jj / R_nom,jj) clipped to [-1, 1] (SEEDS 5.3).
HAMID_INPUT_TERMS: dict[str, tuple[float, float]] = {
    "NS": (-0.5, 0.2), "ZE": (0.0, 0.15), "L": (0.5, 0.2),
}
# [A] Triangular output terms on the normalised universe [-1, 1] (scaled by delta or eta).
ACTION_TERMS: dict[str, tuple[float, float, float]] = {
    "D": (-1.0, -1.0, 0.0), "M": (-0.5, 0.0, 0.5), "I": (0.0, 1.0, 1.0),
}

HAMID_FIS = Mamdani(inputs=(HAMID_INPUT_TERMS, HAMID_INPUT_TERMS), outputs=ACTION_TERMS,
                    rules=HAMID_RULES)

# Escamilla-Ambrosio & Mort's single-input, 3-rule FIS on DoM_n = (S - Sr)/S clipped to
# [-1, 1] (the pluggable alternative of SEEDS 5.3; terms [A]): N -> I, Z -> M, P -> D.
EM_RULES: dict[tuple[str], str] = {("N",): "I", ("Z",): "M", ("P",): "D"}
EM_INPUT_TERMS: dict[str, tuple[float, float]] = {
    "N": (-1.0, 0.35), "Z": (0.0, 0.25), "P": (1.0, 0.35),
}
EM_FIS = Mamdani(inputs=(EM_INPUT_TERMS,), outputs=ACTION_TERMS, rules=EM_RULES)


def fuzzy_adjustment(S: np.ndarray, Sr: np.ndarray, ref: np.ndarray, rules: int = 9
                     ) -> np.ndarray:
    """Normalised action in [-1, 1] per axis (negative = decrease R or Q) from the theoretical
    innovation variances S, the windowed actual ones Sr and the reference scale `ref`."""
    tiny = np.finfo(float).tiny
    if rules == 9:
        u_s = np.clip(np.log10(np.maximum(S, tiny) / ref), -1.0, 1.0)
        u_sr = np.clip(np.log10(np.maximum(Sr, tiny) / ref), -1.0, 1.0)
        return HAMID_FIS(u_sr, u_s)  # inputs in the table's order: (Sr, S)
    if rules == 3:
        return EM_FIS(np.clip((S - Sr) / S, -1.0, 1.0))
    raise ValueError(f"fuzzy rules must be 9 (seed 003) or 3 (Escamilla-Ambrosio & Mort), "
                     f"got {rules}")


# ------------------------------------------------------------- seed 003: fuzzy-r / fuzzy-q


class InnovationWindow:
    """Per-axis ring buffers of the last N innovations (SEEDS 1.6): Sr_jj = mean nu_j^2 (no
    mean removal). A missing cell adds nothing to its axis' buffer."""

    def __init__(self, m: int, size: int) -> None:
        if size < 1:
            raise ValueError(f"innovation window must be >= 1, got {size}")
        self.size = size
        self.buf = np.zeros((m, size))
        self.count = np.zeros(m, dtype=int)

    def push(self, rows: np.ndarray, nu: np.ndarray) -> None:
        slot = self.count[rows] % self.size
        self.buf[rows, slot] = nu
        self.count[rows] += 1

    def full(self, rows: np.ndarray) -> np.ndarray:
        return self.count[rows] >= self.size

    def second_moment(self, rows: np.ndarray) -> np.ndarray:
        return np.mean(self.buf[rows] ** 2, axis=-1)


def _state_axes(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray) -> np.ndarray:
    """For each state component, the measurement axis it feeds most strongly (through
    |H| sum_p |F|^p), or -1 if none: how a per-axis Q scale is spread over the state."""
    F = np.abs(np.asarray(motion.F(x0, 1.0, None), dtype=float))
    H = np.abs(np.asarray(meas.H(x0), dtype=float))
    reach = np.eye(motion.n)
    G = np.zeros_like(H)
    for _ in range(motion.n):
        G += H @ reach
        reach = reach @ F
    axes = np.argmax(G, axis=0)
    return np.where(G.max(axis=0) > 0.0, axes, -1)


class FuzzyAdaptiveKF(ExtendedKalmanFilter):
    """Seed 003's fuzzy-aided KF (Hamid et al. 2018), adapting R (fuzzy-r) or Q (fuzzy-q).

    Per measurement axis j, once N innovations of that axis exist:
        action_j = FIS(Sr_jj, S_jj) in [-1, 1]
        fuzzy-r:  R_jj <- clip(R_jj + step R_nom,jj action_j, [floor, ceiling] R_nom,jj)
        fuzzy-q:  s_j  <- clip(s_j (1 + step action_j), [floor, ceiling])
    where Q = D Q_nom D, D = diag(sqrt(s_axis(i))) scales each state by the factor of the
    measurement axis it feeds (position and velocity of the same axis share s_j).
    R stays diagonal in its adapted entries; off-diagonal entries of R_nom are kept.
    """

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, target: str = "R", window: int = 15, step: float = 0.05,
                 rules: int = 9, floor: float = 0.01, ceiling: float = 100.0) -> None:
        super().__init__(motion, measurement, x0, P0)
        if target not in ("R", "Q"):
            raise ValueError(f"target must be 'R' or 'Q', got {target!r}")
        if not step > 0:
            raise ValueError(f"fuzzy step must be > 0, got {step}")
        self.target = target
        self.kind = "fuzzy-r" if target == "R" else "fuzzy-q"
        self.step_size = float(step)
        self.rules = int(rules)
        fuzzy_adjustment(np.ones(1), np.ones(1), np.ones(1), self.rules)  # validate `rules`
        self.floor, self.ceiling = float(floor), float(ceiling)
        self.R_nom = np.array(measurement.R, dtype=float)
        self.R = self.R_nom.copy()
        self.ref = np.diag(self.R_nom).copy()
        self.q_scale = np.ones(measurement.m)
        self.window = InnovationWindow(measurement.m, int(window))
        axes = _state_axes(motion, measurement, self.x)
        self._axes = axes
        self._rows = np.arange(measurement.m)

    # the process noise the filter currently assumes
    def Q(self, dt: float) -> np.ndarray:
        Q = self.motion.Q(dt)
        if self.target == "R":
            return Q
        s = np.where(self._axes >= 0, self.q_scale[np.maximum(self._axes, 0)],
                     np.exp(np.mean(np.log(self.q_scale))))
        d = np.sqrt(s)
        return d[:, None] * Q * d[None, :]

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        F = self.motion.F(self.x, dt, u)
        self.x, self.P = kf_predict(self.x, self.P, F, self.Q(dt),
                                    fx=self.motion.f(self.x, dt, u))

    def update(self, z: np.ndarray) -> Innovation | None:
        self._rows = np.flatnonzero(np.isfinite(np.asarray(z, dtype=float)))
        return super().update(z)

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        rows = self._rows
        info = self._kalman_update(meas, z, self.R[np.ix_(rows, rows)])
        self._adapt(rows, info)
        return info

    def _adapt(self, rows: np.ndarray, info: Innovation) -> None:
        self.window.push(rows, info.nu)
        ready = self.window.full(rows)
        if not ready.any():
            return
        rows = rows[ready]
        S = np.diag(info.S)[ready]
        Sr = self.window.second_moment(rows)
        action = fuzzy_adjustment(S, Sr, self.ref[rows], self.rules)
        if self.target == "R":
            nom = self.R_nom[rows, rows]
            self.R[rows, rows] = np.clip(self.R[rows, rows] + self.step_size * nom * action,
                                         self.floor * nom, self.ceiling * nom)
        else:
            self.q_scale[rows] = np.clip(self.q_scale[rows] * (1.0 + self.step_size * action),
                                         self.floor, self.ceiling)


_FUZZY_OPTIONS = ("window", "step", "rules", "floor", "ceiling")


@register("fuzzy-r", _FUZZY_OPTIONS)
def _fuzzy_r(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
             **opts: float) -> FuzzyAdaptiveKF:
    """fuzzy-r: R adapted additively (seed 003 eq. R_{k+1} = R_k + AdjR), Q fixed. Options:
    window N (15), step delta/R_nom (0.05), rules (9 = paper, 3 = Escamilla-Ambrosio & Mort),
    floor (0.01) and ceiling (100) on R_jj / R_nom,jj."""
    return FuzzyAdaptiveKF(motion, meas, x0, P0, "R", **_fuzzy_opts(opts))


@register("fuzzy-q", _FUZZY_OPTIONS)
def _fuzzy_q(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
             **opts: float) -> FuzzyAdaptiveKF:
    """fuzzy-q: Q adapted multiplicatively (Q_{k+1} = Q_k AdjQ, AdjQ in [1 - eta, 1 + eta],
    eta = step = 0.05), R fixed; same options as fuzzy-r (floor/ceiling on the Q scale)."""
    return FuzzyAdaptiveKF(motion, meas, x0, P0, "Q", **_fuzzy_opts(opts, "fuzzy-q"))


def _number(kind: str, key: str, value: object) -> float:
    """A finite numeric option (TOML may hand over strings or booleans)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise ValueError(f"filter kind {kind!r}: option {key} must be a number, got {value!r}")
    v = float(value)
    if not np.isfinite(v):
        raise ValueError(f"filter kind {kind!r}: option {key} must be finite, got {v}")
    return v


def _fuzzy_opts(opts: Mapping[str, object], kind: str = "fuzzy-r") -> dict[str, float]:
    out: dict[str, float] = {k: _number(kind, k, v) for k, v in opts.items()}
    for key in ("window", "rules"):
        if key in out:
            if out[key] != int(out[key]):
                raise ValueError(f"filter kind {kind!r}: option {key} must be an integer, "
                                 f"got {out[key]}")
            out[key] = int(out[key])
    return out


# --------------------------------------------------------------- seed 004: SIIM fuzzy EKF


def siim_pa(x: np.ndarray) -> np.ndarray:
    """Monotone linear input membership PA(x) = (x + 1)/2 on [-1, 1] (seed 004 eq. 13, L = 1)."""
    return (np.clip(x, -1.0, 1.0) + 1.0) / 2.0


def siim_pc_inv(w: np.ndarray, M: float = 1.0) -> np.ndarray:
    """Inverse of the output term PC (eq. 16, reconstructed): M(-2 + sqrt(21.25 - (w-4.5)^2)),
    an arc through (0, -M) and (1, +M). NC^-1 = -PC^-1."""
    return M * (-2.0 + np.sqrt(21.25 - (np.asarray(w, dtype=float) - 4.5) ** 2))


SIIM_RULES: tuple[tuple[int, str, int], ...] = (
    # (input index, input term, output sign: +1 = PC, -1 = NC)
    (0, "PA", +1),   # R1: if x1 is PA then u11 is PC
    (0, "NA", -1),   # R2: if x1 is NA then u12 is NC
    (1, "PA", +1),   # R3: if x2 is PA then u21 is PC
    (1, "NA", -1),   # R4: if x2 is NA then u22 is NC
)


def siim_alpha(x1: np.ndarray, x2: np.ndarray, M: float = 1.0) -> np.ndarray:
    """SIIM output alpha = sum w_i u_i / sum w_i with u_i read off the inverse output term at
    the firing degree w_i (eqs. 17-19). Equals (g(x1) + g(x2))/2, g odd and monotone,
    g(0) = 0, g(+-1) = +-M (SEEDS 6.2)."""
    xs = (np.asarray(x1, dtype=float), np.asarray(x2, dtype=float))
    num = 0.0
    den = 0.0
    for i, term, sign in SIIM_RULES:
        pa = siim_pa(xs[i])
        w = pa if term == "PA" else 1.0 - pa
        num = num + w * sign * siim_pc_inv(w, M)
        den = den + w
    return num / den


class SIIMExtendedKalmanFilter(ExtendedKalmanFilter):
    """Seed 004's SIIM fuzzy-logic EKF (Chai 2016), SEEDS 6.2.

    After each (Joseph-form) EKF update:
        x1 = (tr P- - tr P) / tr P-                 (in [0, 1])
        x2 = mean_j clip(nu_j / max(|z_j|, sqrt(R_nom,jj)), -1, 1)   (nu wrapped for angles)
        alpha = SIIM(x1, x2) in [-1, 1]  (normalised universe, M = 1 in eq. 16)
        Q <- (1 - gamma alpha) Q,  R <- (1 + gamma alpha) R,  both clamped to
        [1e-3, 1e3] x nominal (eq. 20 with gamma = the paper's M).
    The x2 denominator is guarded by the measurement's nominal std (relative residuals below
    the noise level are not meaningful); for a scalar measurement the mean is the plain x2.
    """

    kind = "siim-ekf"

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, gamma: float = 1e-4, lo: float = 1e-3, hi: float = 1e3
                 ) -> None:
        super().__init__(motion, measurement, x0, P0)
        self.gamma = float(gamma)
        if not 0.0 <= self.gamma < 1.0:
            raise ValueError(f"siim-ekf gamma must be in [0, 1), got {gamma}")
        self.lo, self.hi = float(lo), float(hi)
        self.q_scale = 1.0
        self.r_scale = 1.0
        self.alpha = 0.0

    def predict(self, dt: float, u: np.ndarray | None = None) -> None:
        F = self.motion.F(self.x, dt, u)
        self.x, self.P = kf_predict(self.x, self.P, F, self.q_scale * self.motion.Q(dt),
                                    fx=self.motion.f(self.x, dt, u))

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        tr_prior = float(np.trace(self.P))
        info = self._kalman_update(meas, z, self.r_scale * meas.R)
        x1 = (tr_prior - float(np.trace(self.P))) / tr_prior if tr_prior > 0 else 0.0
        denom = np.maximum(np.abs(z), np.sqrt(np.diag(meas.R)))
        x2 = float(np.mean(np.clip(info.nu / denom, -1.0, 1.0)))
        self.alpha = float(siim_alpha(x1, x2))
        self.q_scale = float(np.clip(self.q_scale * (1.0 - self.gamma * self.alpha),
                                     self.lo, self.hi))
        self.r_scale = float(np.clip(self.r_scale * (1.0 + self.gamma * self.alpha),
                                     self.lo, self.hi))
        return info


@register("siim-ekf", ("gamma",))
def _siim_ekf(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
              **opts: float) -> SIIMExtendedKalmanFilter:
    """siim-ekf: option gamma (the paper's M; default 1e-4, seed 004 scenario 2)."""
    return SIIMExtendedKalmanFilter(motion, meas, x0, P0,
                                    **{k: _number("siim-ekf", k, v) for k, v in opts.items()})


__all__: Sequence[str] = (
    "Mamdani", "HAMID_FIS", "HAMID_RULES", "LEVELS", "EM_FIS", "FuzzyAdaptiveKF",
    "InnovationWindow", "SIIMExtendedKalmanFilter", "fuzzy_adjustment", "siim_alpha",
    "gaussian_mf", "triangular_mf",
)
