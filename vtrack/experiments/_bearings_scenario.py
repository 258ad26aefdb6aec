"""Seed 000's bearings-only tracking scenario, shared by the `bearings-2`, `bearings-3` and
`ankf` experiments: constants, truth generators, measurements, the PCRLB, and the metrics of
their JSON, on the Monte Carlo harness (vtrack.estimation.montecarlo).

Every filter comes from `vtrack.filter_kinds.make_filter` and runs through the harness,
which steps all Monte Carlo runs of a case as one stack of the core filter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vtrack.estimation.bounds import chi2_band, paired_difference, pcrlb_linear
from vtrack.estimation.linalg import wrap_angle
from vtrack.estimation.models import Bearings, WienerVelocity
from vtrack.estimation.montecarlo import (
    MonteCarloRun,
    each_run,
    monte_carlo,
    nees_series,
    rmse,
    run_rmse,
    squared_error,
)
from vtrack.estimation.parallel import map_tasks
from vtrack.experiments import ExampleRun
from vtrack.filter_kinds import make_filter

# ---------------------------------------------------------------- parameters (SEEDS 2.3)

DT = 0.01                                   # [P][R]
STEPS = 500                                 # [R: ekfs_bot_demo.m]
Q_TRUE = 0.1                                # sigma_v^2, spectral density [P][R]
SIGMA_W = 0.05                              # bearing noise std, rad [P][R]
M0 = np.zeros(4)                            # filter prior mean [P][R]
P0 = np.diag([0.1, 0.1, 10.0, 10.0])        # filter prior covariance [P][R]
X0_TRUE = np.array([0.0, 0.0, 1.0, 0.0])    # true initial state [R]
SENSORS_DEDUCED = np.array([[1.0, -2.0], [1.0, 2.0]])          # [A] deduced, SEEDS 2.3
SENSOR_3 = np.array([1.0 - 2.0 * np.sqrt(3.0), 0.0])            # [P] 1 - 2/tan(30 deg)
SENSORS_THREE = np.vstack([SENSORS_DEDUCED, SENSOR_3])
SENSORS_TOOLBOX = np.array([[-1.0, -2.0], [1.0, 1.0]])          # [R] ekfukf bot demo
TURN_SEGMENTS = ((49, 100), (199, 250), (349, 400))             # 0-based, 51 steps each
TURN_RATE = (np.pi / 2) / 51 / DT                               # quarter turn per segment
TURN_RATE_NOISE = 0.01                                          # per-step N(0,1) scale


# ------------------------------------------------------------------------- randomness


def run_seeds(seed: int, runs: int) -> list[int]:
    """One integer seed per Monte Carlo run, derived from the experiment seed (SEEDS 1.7).

    Run r uses three independent streams: default_rng([s_r, 0]) for the truth (turn-rate or
    process noise), [s_r, 1] for the measurement noise and [s_r, 2] for anything the filter
    draws (a random initial estimate). Run r therefore has the same truth in every experiment
    and every geometry, which makes comparisons paired.
    """
    return [int(s) for s in np.random.SeedSequence(seed).generate_state(runs, dtype=np.uint32)]


def _rng(s: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([s, stream])


# ------------------------------------------------------------------------------ truth


def turn_transition(a: np.ndarray, dt: float) -> np.ndarray:
    """expm(Fc(a) dt) for Fc = [[0,0,1,0],[0,0,0,1],[0,0,0,a],[0,0,-a,0]] in closed form
    (..., 4, 4): the velocity turns by -a dt, the position integrates it. Equal to
    scipy.linalg.expm to rounding (a unit test checks it); batched expm is slow here."""
    a = np.asarray(a, dtype=float)
    th = a * dt
    c, s = np.cos(th), np.sin(th)
    small = np.abs(a) < 1e-12
    safe = np.where(small, 1.0, a)
    s_a = np.where(small, dt, s / safe)                       # int_0^dt cos(a t) dt
    c_a = np.where(small, 0.5 * a * dt * dt, (1.0 - c) / safe)  # int_0^dt sin(a t) dt
    Phi = np.zeros(a.shape + (4, 4))
    Phi[..., 0, 0] = Phi[..., 1, 1] = 1.0
    Phi[..., 0, 2], Phi[..., 0, 3] = s_a, c_a
    Phi[..., 1, 2], Phi[..., 1, 3] = -c_a, s_a
    Phi[..., 2, 2], Phi[..., 2, 3] = c, s
    Phi[..., 3, 2], Phi[..., 3, 3] = -s, c
    return Phi


def turn_rates(seeds: list[int]) -> np.ndarray:
    """Per-step turn rates of the toolbox path (runs, 500): (pi/2)/51/dt + 0.01 N(0,1) on the
    three 51-step segments, 0 elsewhere; drawn from each run's truth stream."""
    a = np.zeros((len(seeds), STEPS))
    for r, s in enumerate(seeds):
        rng = _rng(s, 0)
        for lo, hi in TURN_SEGMENTS:
            a[r, lo:hi] = TURN_RATE + TURN_RATE_NOISE * rng.standard_normal(hi - lo)
    return a


def turning_truth(seeds: list[int]) -> np.ndarray:
    """The toolbox's coordinated-turn path (SEEDS 2.3), states after each of the 500 steps.

    x_{k+1} = expm(Fc(a_k) dt) x_k from [0, 0, 1, 0] with the turn rates of turn_rates();
    measurements are taken after each propagation. Returns (runs, 500, 4).
    """
    Phi = turn_transition(turn_rates(seeds), DT)
    x = np.broadcast_to(X0_TRUE, (len(seeds), 4)).copy()
    out = np.empty((len(seeds), STEPS, 4))
    for k in range(STEPS):
        x = np.einsum("rij,rj->ri", Phi[:, k], x)
        out[:, k] = x
    return out


def wiener_truth(seeds: list[int], q: float = Q_TRUE, dt: float = DT, steps: int = STEPS,
                 x0: np.ndarray = X0_TRUE) -> np.ndarray:
    """Model-matched truth: x_k = F x_{k-1} + v, v ~ N(0, Q(q)) from x0 (SEEDS 2.6).
    Returns (runs, steps, 4)."""
    model = WienerVelocity(q)
    F, L = model.transition(dt), np.linalg.cholesky(model.Q(dt))
    out = np.empty((len(seeds), steps, 4))
    for r, s in enumerate(seeds):
        w = _rng(s, 0).standard_normal((steps, 4)) @ L.T
        x = np.array(x0, dtype=float)
        for k in range(steps):
            x = F @ x + w[k]
            out[r, k] = x
    return out


def randomised_priors(seeds: list[int], x0: np.ndarray = X0_TRUE, P0: np.ndarray = P0
                      ) -> np.ndarray:
    """Initial estimates m0_r = x0 + N(0, P0) from each run's filter stream: the truth is then a
    sample of the filter's prior N(m0, P0), as the strict PCRLB needs (SEEDS 7.2)."""
    L = np.linalg.cholesky(P0)
    return np.array([x0 + L @ _rng(s, 2).standard_normal(4) for s in seeds])


def measure(truth: np.ndarray, sensors: np.ndarray, sigma: float | np.ndarray,
            seeds: list[int]) -> np.ndarray:
    """Bearings z = wrap(atan2(y - sy, x - sx) + sigma_k N(0,1)) of every state (runs, K, m).

    `sigma` is a number or one value per step (K,). Sensor j's noise is the j-th block of K
    normals of the run's measurement stream, so adding a sensor leaves the others' noise
    unchanged (paired comparisons between geometries)."""
    meas = Bearings(sensors, 1.0)
    runs, K, _ = truth.shape
    noise = np.stack([_rng(s, 1).standard_normal((meas.m, K)).T for s in seeds])
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (K,))[None, :, None]
    return wrap_angle(meas.h(truth) + sig * noise)


# --------------------------------------------------------------------------- filtering


_DIAGNOSTICS = {  # per-step diagnostics of the adaptive kinds (diag of the R used, fading)
    "ankf1": {"R_used": lambda f: each_run(f, np.diagonal(f.R_used, axis1=-2, axis2=-1))},
    "ankf2": {"R_used": lambda f: each_run(f, np.diagonal(f.R_used, axis1=-2, axis2=-1)),
              "lambda_P": lambda f: each_run(f, f.lambda_P, 0)},
}


def run_filter(kind: str, motion: WienerVelocity, meas: Bearings, Z: np.ndarray,
               x0s: np.ndarray, P0: np.ndarray, batch: bool = True, dt: float = DT,
               **options: object) -> MonteCarloRun:
    """Run filter `kind` over every run (the harness, montecarlo.monte_carlo): all runs
    stepped together as one stack of the core filter (batch), or one at a time."""
    return monte_carlo(kind, lambda r: make_filter(kind, motion, meas, x0s[r], P0, **options),
                       Z, dt, record=_DIAGNOSTICS.get(kind), batch=batch)


# ----------------------------------------------------------------------------- bounds


def pcrlb_variance(truth: np.ndarray, sensors: np.ndarray, sigma: float | np.ndarray,
                   q: float = Q_TRUE, dt: float = DT, P0: np.ndarray = P0) -> np.ndarray:
    """Position part of the PCRLB, [J_k^-1]_xx + [J_k^-1]_yy per step (K,) (SEEDS 7.2).

    One information recursion for the Wiener-velocity model with spectral density q and the
    prior P0; E[H' R^-1 H] at each step is averaged over the true states of all runs (H at the
    true state; sigma may vary per step). For the toolbox turning truth, which is not a sample
    of this model, the result is a model-based reference floor, not a strict bound."""
    meas = Bearings(sensors, 1.0)
    runs, K, _ = truth.shape
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (K,))
    info = np.zeros((K, 4, 4))
    for k in range(K):
        acc = np.zeros((4, 4))
        for r in range(runs):
            H = meas.H(truth[r, k])
            acc += H.T @ H
        info[k] = acc / runs / sig[k] ** 2
    model = WienerVelocity(q)
    bound = pcrlb_linear(model.transition(dt), model.Q(dt), P0, info)
    return bound[:, 0, 0] + bound[:, 1, 1]


# ---------------------------------------------------------------------------- metrics


def squared_position_error(run: MonteCarloRun, truth: np.ndarray) -> np.ndarray:
    """Delta x^2 + Delta y^2 per run and step (runs, K); NaN for failed runs."""
    return squared_error(run.x, truth, slice(0, 2))


def per_run_rmse(run: MonteCarloRun, truth: np.ndarray) -> np.ndarray:
    """sqrt(mean_k (Delta x_k^2 + Delta y_k^2)) of each run (SEEDS 1.7), NaN if failed."""
    return run_rmse(squared_position_error(run, truth))


def summarize(run: MonteCarloRun, truth: np.ndarray, bound_var: np.ndarray | None,
              paper_rmse: float | None = None) -> dict[str, float | int | None]:
    """The JSON entry of one filter (INTERFACE.md `vtrack experiment`; SEEDS 1.7, 7.2, 7.3).

    rmse: root of the mean over runs and steps of the squared position error (finite runs);
    rmse_mean_of_runs: mean of the per-run RMSEs (the toolbox's table value), with its standard
    error rmse_mean_of_runs_se; median of the per-run RMSEs; diverged: runs that failed or whose
    RMSE exceeds 10x the median (then also rmse_without_diverged); pcrlb_rmse:
    sqrt(mean_k bound_k), rmse_over_pcrlb and rmse_over_pcrlb_min_step, the smallest ratio of
    the per-step RMSE over runs to the per-step bound (SEEDS 7.2: below 1 beyond Monte Carlo
    error means a bug or an invalid comparison); anees:
    NEES averaged over runs and steps; nees_steps_in_band: fraction of steps whose run-averaged
    NEES lies in the two-sided 95% chi2 band."""
    se = squared_position_error(run, truth)
    ok = ~run.failed & np.all(np.isfinite(se), axis=1)
    rr = run_rmse(se[ok])
    median = float(np.median(rr)) if ok.any() else float("nan")
    out: dict[str, float | int | None] = {
        "rmse": rmse(se[ok]) if ok.any() else float("nan"),
        "rmse_mean_of_runs": float(np.mean(rr)) if ok.any() else float("nan"),
        "rmse_mean_of_runs_se": float(np.std(rr, ddof=1) / np.sqrt(len(rr)))
        if len(rr) > 1 else float("nan"),
        "median": median,
        "diverged": int(np.sum(~ok) + np.sum(rr > 10.0 * median)),
        "failed": int(np.sum(~ok)),
    }
    keep = ok.copy()
    keep[ok] = rr <= 10.0 * median
    if out["diverged"] and keep.any():
        out["rmse_without_diverged"] = float(np.sqrt(np.mean(se[keep])))
    if bound_var is not None:
        out["pcrlb_rmse"] = float(np.sqrt(np.mean(bound_var)))
        out["rmse_over_pcrlb"] = out["rmse"] / out["pcrlb_rmse"]
        if ok.any():
            step_rmse = np.sqrt(np.mean(se[ok], axis=0))
            out["rmse_over_pcrlb_min_step"] = float(np.min(step_rmse / np.sqrt(bound_var)))
    ne = nees_series(run, truth)[ok]
    ne = ne[np.all(np.isfinite(ne), axis=1)]
    if len(ne):
        out["anees"] = float(np.mean(ne))
        lo, hi = chi2_band(truth.shape[-1], len(ne))
        per_step = np.mean(ne, axis=0)
        out["nees_steps_in_band"] = float(np.mean((per_step >= lo) & (per_step <= hi)))
    if paper_rmse is not None:
        out["paper_rmse"] = paper_rmse
    return out


def per_step_rmse(run: MonteCarloRun, truth: np.ndarray) -> np.ndarray:
    """sqrt(mean over (finite) runs of the squared position error) per step (K,)."""
    se = squared_position_error(run, truth)
    se = se[np.all(np.isfinite(se), axis=1)]
    return np.sqrt(np.mean(se, axis=0))


def json_clean(obj: object) -> object:
    """Make a structure strict-JSON safe: numpy scalars to Python, non-finite floats to None."""
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return json_clean(obj.tolist())
    if isinstance(obj, dict):
        return {str(k): json_clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_clean(v) for v in obj]
    return obj


# ------------------------------------------------------------------------ one scenario


@dataclass
class Scenario:
    """One seed-000 set-up: geometry, truth generator and the filter's (maybe wrong) model.

    truth "turn" is the toolbox's turning path (the filter starts at the fixed prior mean M0);
    "wiener" is the model-matched truth (Wiener velocity with q_true from x0_true, `steps`
    steps of dt) with a randomised prior mean per run, m0 ~ N(x0_true, prior_cov). q_true and
    sigma_true (a number or one value per step) also define the PCRLB; q_filter,
    sigma_filter and prior_cov are what the filters assume."""

    sensors: np.ndarray
    truth: str = "turn"
    q_true: float = Q_TRUE
    q_filter: float = Q_TRUE
    sigma_true: float | np.ndarray = SIGMA_W
    sigma_filter: float = SIGMA_W
    dt: float = DT
    steps: int = STEPS
    x0_true: np.ndarray = field(default_factory=X0_TRUE.copy)
    prior_cov: np.ndarray = field(default_factory=P0.copy)

    def __post_init__(self) -> None:
        if self.truth == "turn" and (self.dt, self.steps) != (DT, STEPS):
            raise ValueError("the toolbox's turning path has dt = 0.01 and 500 steps")

    def parameters(self) -> dict[str, object]:
        """The scenario's parameters for the JSON."""
        sig = np.asarray(self.sigma_true, dtype=float)
        if sig.ndim:
            change = int(np.flatnonzero(np.diff(sig))[0] + 1) if np.any(np.diff(sig)) else None
            sigma_true: object = {"before": float(sig[0]), "after": float(sig[-1]),
                                  "change_at_step": change}
        else:
            sigma_true = float(sig)
        return {
            "sensors": self.sensors.tolist(),
            "truth": {"turn": "toolbox turning path (SEEDS 2.3): 500 steps, dt 0.01, expm "
                              "propagation, turn-rate noise 0.01 N(0,1), x0 = [0, 0, 1, 0]; "
                              "filter prior mean m0 = [0, 0, 0, 0]",
                      "wiener": "model-matched: Wiener velocity with the true sigma_v^2 from "
                                f"x0 = [{', '.join(f'{v:g}' for v in self.x0_true)}]; filter "
                                "prior mean m0 ~ N(x0, P0) per run"
                      }[self.truth],
            "dt": self.dt, "steps": self.steps,
            "sigma_v2_true": self.q_true if self.truth == "wiener" else None,
            "sigma_v2_filter": self.q_filter,
            "sigma_w_true": sigma_true,
            "sigma_w_filter": self.sigma_filter,
            "P0_diag": np.diag(self.prior_cov).tolist(),
        }


@dataclass
class CaseRun:
    """Everything one scenario produced over the Monte Carlo runs."""

    scenario: Scenario
    seeds: list[int]
    truth: np.ndarray
    Z: np.ndarray
    x0s: np.ndarray
    bound_var: np.ndarray
    runs: dict[str, MonteCarloRun]
    options: dict[str, dict[str, object]]


@dataclass
class _Data:
    """One scenario's runs before the filters: truth, measurements, priors and the PCRLB."""

    truth: np.ndarray
    Z: np.ndarray
    x0s: np.ndarray
    bound_var: np.ndarray


def _data(scenario: Scenario, seeds: list[int]) -> _Data:
    if scenario.truth == "turn":
        truth = turning_truth(seeds)
        x0s = np.broadcast_to(M0, (len(seeds), 4)).copy()
    elif scenario.truth == "wiener":
        truth = wiener_truth(seeds, scenario.q_true, scenario.dt, scenario.steps,
                             scenario.x0_true)
        x0s = randomised_priors(seeds, scenario.x0_true, scenario.prior_cov)
    else:
        raise ValueError(f"unknown truth {scenario.truth!r}")
    Z = measure(truth, scenario.sensors, scenario.sigma_true, seeds)
    bound_var = pcrlb_variance(truth, scenario.sensors, scenario.sigma_true, scenario.q_true,
                               scenario.dt, scenario.prior_cov)
    return _Data(truth, Z, x0s, bound_var)


# the kinds by their cost per update, the slowest first (the iterated updates relinearise
# several times a step); tasks are handed out in this order, so the workers finish together
SLOWEST_FIRST = ("iplf", "iekf", "ckf", "ukf", "ankf2", "ankf1", "ekf")


def simulate(scenario: Scenario, seeds: list[int],
             filters: dict[str, dict[str, object]], batch: bool = True) -> CaseRun:
    """Truth, measurements, the PCRLB and every filter of `filters` ({kind: options}) on the
    same runs (paired); batch as in run_filter. simulate_all of one scenario."""
    return simulate_all([(scenario, filters)], seeds, batch)[0]


def simulate_all(cases: list[tuple[Scenario, dict[str, dict[str, object]]]], seeds: list[int],
                 batch: bool = True) -> list[CaseRun]:
    """simulate() of each (scenario, filters) pair. The scenarios' data, then every filter of
    every scenario, run side by side in worker processes (parallel.map_tasks), the filters
    SLOWEST_FIRST: one task a filter, not a scenario, so that no worker is left with two
    scenarios' iterated filters while the other idles."""
    data = map_tasks(lambda case: _data(case[0], seeds), cases)
    rank = {kind: i for i, kind in enumerate(SLOWEST_FIRST)}
    tasks = sorted(((i, kind) for i, (_, filters) in enumerate(cases) for kind in filters),
                   key=lambda task: rank.get(task[1], len(rank)))

    def run(task: tuple[int, str]) -> MonteCarloRun:
        i, kind = task
        sc, d = cases[i][0], data[i]
        return run_filter(kind, WienerVelocity(sc.q_filter), Bearings(sc.sensors, sc.sigma_filter),
                          d.Z, d.x0s, sc.prior_cov, batch, dt=sc.dt, **cases[i][1][kind])

    done = dict(zip(tasks, map_tasks(run, tasks)))
    return [CaseRun(sc, seeds, d.truth, d.Z, d.x0s, d.bound_var,
                    {kind: done[(i, kind)] for kind in filters}, dict(filters))
            for i, ((sc, filters), d) in enumerate(zip(cases, data))]


def case_results(case: CaseRun, paper: dict[str, float] | None = None
                 ) -> dict[str, dict[str, object]]:
    """`results` of one case: per filter the summarize() entry, its options and adaptation
    diagnostics (mean adapted R per half of the run, mean fading factor)."""
    paper = paper or {}
    out: dict[str, dict[str, object]] = {}
    half = case.scenario.steps // 2
    for kind, run in case.runs.items():
        entry = summarize(run, case.truth, case.bound_var, paper.get(kind))
        if case.options.get(kind):
            entry["options"] = dict(case.options[kind])
        ok = ~run.failed
        if "R_used" in run.series and ok.any():
            r_used = run.series["R_used"][ok]
            entry["r_used_mean_first_half"] = float(np.mean(r_used[:, :half]))
            entry["r_used_mean_second_half"] = float(np.mean(r_used[:, half:]))
        if "lambda_P" in run.series and ok.any():
            entry["lambda_p_mean"] = float(np.mean(run.series["lambda_P"][ok]))
        out[kind] = entry
    return out


def comparisons(case: CaseRun, reference: str = "ekf") -> dict[str, dict[str, float | int]]:
    """Paired per-run RMSE differences `kind - reference` (mean, standard error, runs)."""
    if reference not in case.runs:
        return {}
    ref = per_run_rmse(case.runs[reference], case.truth)
    return {f"{kind}-{reference}": paired_difference(per_run_rmse(run, case.truth), ref)
            for kind, run in case.runs.items() if kind != reference}


def example_run(case: CaseRun, r: int = 0) -> ExampleRun:
    """Run r's series for plots, plus Monte Carlo curves in extra_series: `rmse/<kind>` (per-step
    RMSE over runs), `pcrlb` (per-step position bound), `nees/<kind>` (run-averaged NEES), and
    for adaptive filters `R_used/<kind>` (diag of the R used, run r) and `lambda_P/<kind>`."""
    extra: dict[str, np.ndarray] = {"pcrlb": np.sqrt(case.bound_var)}
    nees_r: dict[str, np.ndarray] = {}
    for kind, run in case.runs.items():
        extra[f"rmse/{kind}"] = per_step_rmse(run, case.truth)
        ne = nees_series(run, case.truth)
        nees_r[kind] = ne[r]
        ne = ne[np.all(np.isfinite(ne), axis=1)]
        if len(ne):
            extra[f"nees/{kind}"] = np.mean(ne, axis=0)
        for name, series in run.series.items():
            extra[f"{name}/{kind}"] = series[r]
    return ExampleRun(
        times=case.scenario.dt * np.arange(1, case.scenario.steps + 1),
        truth=case.truth[r],
        estimates={k: v.x[r] for k, v in case.runs.items()},
        covariances={k: v.P[r] for k, v in case.runs.items()},
        nees=nees_r,
        sensors=np.asarray(case.scenario.sensors),
        measurements=case.Z[r],
        extra_series=extra,
    )
