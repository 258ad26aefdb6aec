"""Fuzzy-adaptive filter kinds fuzzy-r and fuzzy-q of seed 003 (Hamid et al. 2018,
SEEDS 5.3), and the Mamdani inference they use.

Both are the core EKF (vtrack.estimation.filters.ExtendedKalmanFilter) with its Q/R hooks:
per measurement axis j, the windowed "actual" innovation variance Sr_jj = (1/N) sum nu_j^2
is compared with the filter's theoretical S_jj = [H P- H' + R]_jj by the nine-rule Mamdani
FIS of the paper's Table 1; the output changes R additively (R_jj += AdjR) or Q
multiplicatively (Q *= AdjQ). The adapted Q or R applies from the next step on
(R_{k+1} = R_k + AdjR in the paper's notation); the Joseph form keeps P valid with the
resulting non-optimal gains.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from vtrack.adaptive.innovation_windows import InnovationVarianceWindow
from vtrack.estimation.filters import ExtendedKalmanFilter
from vtrack.estimation.kalman import Innovation
from vtrack.estimation.models import MeasurementModel, MotionModel
from vtrack.estimation.options import float_option, int_option
from vtrack.estimation.registry import register

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


def _state_axes(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray) -> np.ndarray:
    """For each state component, the measurement axis it feeds most strongly (through
    |H| sum_p |F|^p), or -1 if none: how a per-axis Q scale is spread over the state.
    (n,), or (..., n) for a stack of states x0 (..., n)."""
    F = np.abs(np.asarray(motion.F(x0, 1.0, None), dtype=float))
    H = np.abs(np.asarray(meas.H(x0), dtype=float))
    reach = np.eye(motion.n)
    G = np.zeros(np.broadcast_shapes(H.shape, x0.shape[:-1] + (1, 1)))
    for _ in range(motion.n):
        G = G + H @ reach
        reach = reach @ F
    axes = np.argmax(G, axis=-2)
    return np.where(G.max(axis=-2) > 0.0, axes, -1)


class FuzzyAdaptiveKF(ExtendedKalmanFilter):
    """Seed 003's fuzzy-aided KF (Hamid et al. 2018), adapting R (fuzzy-r) or Q (fuzzy-q).

    Per measurement axis j, once N innovations of that axis exist:
        action_j = FIS(Sr_jj, S_jj) in [-1, 1]
        fuzzy-r:  R_jj <- clip(R_jj + step R_nom,jj action_j, [floor, ceiling] R_nom,jj)
        fuzzy-q:  s_j  <- clip(s_j (1 + step action_j), [floor, ceiling])
    where Q = D Q_nom D, D = diag(sqrt(s_axis(i))) scales each state by the factor of the
    measurement axis it feeds (position and velocity of the same axis share s_j).
    R stays diagonal in its adapted entries; off-diagonal entries of R_nom are kept.
    For a stack of runs R and q_scale carry the leading run axis.
    """

    def __init__(self, motion: MotionModel, measurement: MeasurementModel, x0: np.ndarray,
                 P0: np.ndarray, target: str = "R", window: int = 15, step: float = 0.05,
                 rules: int = 9, floor: float = 0.01, ceiling: float = 100.0) -> None:
        super().__init__(motion, measurement, x0, P0)
        if target not in ("R", "Q"):
            raise ValueError(f"target must be 'R' or 'Q', got {target!r}")
        self.target = target
        self.kind = "fuzzy-r" if target == "R" else "fuzzy-q"
        self.step_size = float_option("step", step, 0.0)
        self.rules = int_option("rules", rules, 1)
        fuzzy_adjustment(np.ones(1), np.ones(1), np.ones(1), self.rules)  # validate `rules`
        self.floor, self.ceiling = float_option("floor", floor), float_option("ceiling", ceiling)
        runs = self.x.shape[:-1]
        self.R_nom = np.array(measurement.R, dtype=float)
        self.R = np.broadcast_to(self.R_nom, runs + self.R_nom.shape).copy()
        self.ref = np.diag(self.R_nom).copy()
        self.q_scale = np.ones(runs + (measurement.m,))
        self.window = InnovationVarianceWindow(measurement.m, int_option("window", window, 1),
                                               runs)
        self._axes = _state_axes(motion, measurement, self.x)

    def process_noise(self, dt: float) -> np.ndarray:
        """The process noise the filter currently assumes: Q_nom, or (fuzzy-q) D Q_nom D."""
        Q = self.motion.Q(dt)
        if self.target == "R":
            return Q
        s = np.where(self._axes >= 0,
                     np.take_along_axis(self.q_scale, np.maximum(self._axes, 0), axis=-1),
                     np.exp(np.mean(np.log(self.q_scale), axis=-1, keepdims=True)))
        d = np.sqrt(s)
        return d[..., :, None] * Q * d[..., None, :]

    def measurement_noise(self, meas: MeasurementModel) -> np.ndarray:
        """The adapted R on the rows of `meas`."""
        rows = meas.row_indices()
        return self.R[..., rows, :][..., rows]

    def _update(self, meas: MeasurementModel, z: np.ndarray) -> Innovation:
        info = super()._update(meas, z)
        self._adapt(meas.row_indices(), info)
        return info

    def _adapt(self, rows: np.ndarray, info: Innovation) -> None:
        self.window.push(rows, info.nu)
        ready = self.window.full(rows)
        if not ready.any():
            return
        rows = rows[ready]
        S = np.diagonal(info.S, axis1=-2, axis2=-1)[..., ready]
        Sr = self.window.second_moment(rows)
        action = fuzzy_adjustment(S, Sr, self.ref[rows], self.rules)
        if self.target == "R":
            nom = self.R_nom[rows, rows]
            self.R[..., rows, rows] = np.clip(
                self.R[..., rows, rows] + self.step_size * nom * action,
                self.floor * nom, self.ceiling * nom)
        else:
            self.q_scale[..., rows] = np.clip(
                self.q_scale[..., rows] * (1.0 + self.step_size * action),
                self.floor, self.ceiling)


_FUZZY_OPTIONS = ("window", "step", "rules", "floor", "ceiling")


@register("fuzzy-r", _FUZZY_OPTIONS)
def _fuzzy_r(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
             **opts: float) -> FuzzyAdaptiveKF:
    """fuzzy-r: R adapted additively (seed 003 eq. R_{k+1} = R_k + AdjR), Q fixed. Options:
    window N (15), step delta/R_nom (0.05), rules (9 = paper, 3 = Escamilla-Ambrosio & Mort),
    floor (0.01) and ceiling (100) on R_jj / R_nom,jj."""
    return FuzzyAdaptiveKF(motion, meas, x0, P0, "R", **opts)


@register("fuzzy-q", _FUZZY_OPTIONS)
def _fuzzy_q(motion: MotionModel, meas: MeasurementModel, x0: np.ndarray, P0: np.ndarray,
             **opts: float) -> FuzzyAdaptiveKF:
    """fuzzy-q: Q adapted multiplicatively (Q_{k+1} = Q_k AdjQ, AdjQ in [1 - eta, 1 + eta],
    eta = step = 0.05), R fixed; same options as fuzzy-r (floor/ceiling on the Q scale)."""
    return FuzzyAdaptiveKF(motion, meas, x0, P0, "Q", **opts)


__all__: Sequence[str] = (
    "Mamdani", "HAMID_FIS", "HAMID_RULES", "LEVELS", "EM_FIS", "FuzzyAdaptiveKF",
    "fuzzy_adjustment", "gaussian_mf", "triangular_mf",
)
