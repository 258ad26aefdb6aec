"""The Monte Carlo harness (SEEDS 1.7, 7.3): filters over runs x steps, and their statistics.

`run_sequence` steps one filter over one measurement sequence (a `vtrack filter` log) or a
filter holding a stack of runs over theirs, and collects the posterior means, covariances and
NIS; `monte_carlo` does it for every run of a Monte Carlo set: the runs that miss the same
measurement cells are stepped together as one stack of the core filter (the same code as one
track, with a leading run axis: numpy's batched solve, Cholesky and matmul instead of one
small call per run), and the runs whose filter failed are marked. The functions below them turn those arrays into what the
experiments report: RMSE over runs and steps and per run, NEES and ANEES with the chi-square
band, NIS, and paired differences with standard errors (bounds.paired_difference).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from vtrack.estimation.bounds import chi2_band, nees
from vtrack.estimation.filters import GaussianFilter
from vtrack.estimation.linalg import EstimationError

Recorder = Callable[[GaussianFilter], object]
"""A per-step diagnostic read off the filter after each step (e.g. an adapted R)."""


@dataclass
class FilterOutput:
    """One filter over one sequence of K steps: posterior means x (K, n) and covariances
    P (K, n, n) after each step, the NIS of each update and its degrees of freedom (NaN and
    0 where nothing was measured), the prior (x0, P0) and the recorded diagnostics (K, ...)."""

    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray
    nis_dof: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    series: dict[str, np.ndarray] = field(default_factory=dict)


class StepError(EstimationError):
    """The filter failed at step `step` (0-based); `cause` says why in one line."""

    def __init__(self, step: int, cause: str) -> None:
        super().__init__(f"step {step}: {cause}")
        self.step, self.cause = step, cause


def run_sequence(filt: GaussianFilter, z: np.ndarray, dt: float | np.ndarray,
                 u: np.ndarray | None = None, record: Mapping[str, Recorder] | None = None,
                 before_step: Callable[[GaussianFilter, int], None] | None = None,
                 require_finite: bool = False) -> FilterOutput:
    """Step `filt` over z (K, m): at step k predict over dt (a number, or dt[k]) with input
    u[k], then update with the finite cells of z[k] (NaN = missing). `before_step(filt, k)`
    may change the filter before step k (e.g. a time-varying R); `record` reads diagnostics
    after each step.

    A filter holding a stack of R runs (GaussianFilter) is stepped over z (R, K, m) and
    u (R, K, p) the same way; every output then has the leading run axis (x (R, K, n), ...),
    and a recorder returns one value per run (or one number for all).

    Any estimation failure (non-PD covariance, inf cell, overflow; with require_finite also
    a non-finite posterior) raises StepError naming the step."""
    batch = filt.x.shape[:-1]
    K = z.shape[-2]
    n = filt.x.shape[-1]
    dts = np.broadcast_to(np.asarray(dt, dtype=float), (K,))
    out = FilterOutput(x=np.empty(batch + (K, n)), P=np.empty(batch + (K, n, n)),
                       nis=np.full(batch + (K,), np.nan),
                       nis_dof=np.zeros(batch + (K,), dtype=int), x0=filt.x.copy(),
                       P0=filt.P.copy())
    values: dict[str, list] = {name: [] for name in (record or {})}
    with np.errstate(all="ignore"):  # warnings would break the CLI's one-line error contract
        for k in range(K):
            try:
                if before_step is not None:
                    before_step(filt, k)
                filt.predict(float(dts[k]), None if u is None else u[..., k, :])
                info = filt.update(z[..., k, :])
                x, P = filt.x, filt.P
                if require_finite and not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
                    raise EstimationError("the posterior mean or covariance is not finite")
            except (EstimationError, np.linalg.LinAlgError, ArithmeticError) as exc:
                raise StepError(k, _cause(exc)) from exc
            out.x[..., k, :], out.P[..., k, :, :] = x, P
            if info is not None:
                out.nis[..., k], out.nis_dof[..., k] = info.nis, info.nu.shape[-1]
            for name, read in (record or {}).items():
                values[name].append(_per_run(read(filt), batch))
    out.series = {name: np.stack(v, axis=len(batch)) if v else np.empty(batch + (0,))
                  for name, v in values.items()}
    return out


def each_run(filt: GaussianFilter, value: np.ndarray, ndim: int = 1) -> np.ndarray:
    """A recorder's diagnostic of `ndim` axes (a vector: ndim 1) with one row per run of the
    filter's stack, broadcast if it is one value for all (e.g. the model's R before any
    adaptation); unchanged for one track."""
    value = np.asarray(value, dtype=float)
    return np.broadcast_to(value, filt.x.shape[:-1] + value.shape[value.ndim - ndim:])


def _per_run(value: object, batch: tuple[int, ...]) -> np.ndarray:
    """A recorded diagnostic as a float array of its own (a copy: filters update their state
    in place); one number stands for every run of a stack."""
    value = np.array(value, dtype=float)
    return np.broadcast_to(value, batch) if value.ndim == 0 else value


def _cause(exc: BaseException) -> str:
    cause = " ".join(str(exc).split())
    if isinstance(exc, OverflowError):
        return "numerical overflow (is the time step or a value absurdly large?)"
    if not isinstance(exc, EstimationError):
        return f"numerical failure ({type(exc).__name__}: {cause})"
    return cause


@dataclass
class MonteCarloRun:
    """One filter over R runs of K steps: x (R, K, n), P (R, K, n, n), nis and nis_dof
    (R, K), the priors x0 (R, n) and P0 (R, n, n), diagnostics (R, K, ...); `failed[r]` is
    True when run r's filter raised (its arrays are NaN)."""

    kind: str
    x: np.ndarray
    P: np.ndarray
    failed: np.ndarray
    nis: np.ndarray | None = None
    nis_dof: np.ndarray | None = None
    x0: np.ndarray | None = None
    P0: np.ndarray | None = None
    series: dict[str, np.ndarray] = field(default_factory=dict)

    def with_prior(self, r: int) -> tuple[np.ndarray, np.ndarray]:
        """Run r's means (K+1, n) and covariances (K+1, n, n), row 0 being the prior."""
        return (np.concatenate([self.x0[r][None], self.x[r]]),
                np.concatenate([self.P0[r][None], self.P[r]]))


Factory = Callable[[object], GaussianFilter]
"""Builds the filter of some runs: called with an index array of runs (the filter then holds
that stack, x (len, n)), or with one run's int index (a one-track filter)."""


def missing_patterns(Z: np.ndarray) -> list[np.ndarray]:
    """The runs of Z (R, K, m) grouped by which cells they miss (NaN) over the whole
    sequence: runs of one group miss the same cells at every step and can be stepped as one
    stack (GaussianFilter.update). Groups in order of their first run."""
    keys = np.isfinite(Z).reshape(len(Z), -1)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    return [np.flatnonzero(inverse.reshape(-1) == g) for g in order]


def monte_carlo(kind: str, factory: Factory, Z: np.ndarray, dt: float | np.ndarray,
                U: np.ndarray | None = None, record: Mapping[str, Recorder] | None = None,
                before_step: Callable[[GaussianFilter, int], None] | None = None,
                batch: bool = True) -> MonteCarloRun:
    """Run the filter of `factory` over the measurements Z[r] (K, m) (inputs U[r]) of every
    run r (run_sequence).

    batch (the default): the runs that miss the same cells (missing_patterns) are stepped
    together, `factory(runs)` building one filter for the index array `runs`; that is the
    same code as one track, with a leading run axis. Kinds that cannot (`batched` False, or
    a factory that does not build a stack) and batch=False run one run at a time, each
    filter built for one track, `factory(r)`. A run whose filter cannot be built or
    fails is marked failed and left NaN; the others are unaffected (paired comparisons stay
    paired): when a stack fails, its runs are stepped again one at a time to find the
    failing ones. Whenever batch=True steps runs one at a time, a warning on stderr says
    which kind, how many runs and why (it is the slow path)."""
    outs: list[FilterOutput | None] = [None] * len(Z)
    sizes: set[int] = set()
    for runs in missing_patterns(Z) if batch else [[r] for r in range(len(Z))]:
        stacked, why = _run_stack(factory, np.asarray(runs), Z, dt, U, record, before_step) \
            if batch and len(runs) > 1 else (None, None)
        if stacked is None:
            if why is not None:
                _warn(f"{kind}: {len(runs)} runs stepped one at a time, not as one stack "
                      f"({why})")
            stacked = []
            for r in runs:
                out, n = _run_one(factory, int(r), Z, dt, U, record, before_step)
                stacked.append(out)
                sizes.update([] if n is None else [n])
        for r, out in zip(runs, stacked):
            outs[r] = out
    sizes.update(o.x.shape[-1] for o in outs if o is not None)
    if not sizes:
        raise EstimationError(f"filter {kind!r} could not be built for any run")
    n = sizes.pop()
    K = Z.shape[1]
    good = next((o for o in outs if o is not None), None)
    blank = FilterOutput(x=np.full((K, n), np.nan), P=np.full((K, n, n), np.nan),
                         nis=np.full(K, np.nan), nis_dof=np.zeros(K, dtype=int),
                         x0=np.full(n, np.nan), P0=np.full((n, n), np.nan),
                         series={name: np.full(good.series[name].shape if good else K, np.nan)
                                 for name in record or {}})
    rows = [blank if o is None else o for o in outs]

    def stack(name: str) -> np.ndarray:
        return np.stack([getattr(o, name) for o in rows])

    return MonteCarloRun(kind=kind, x=stack("x"), P=stack("P"),
                         failed=np.array([o is None for o in outs]), nis=stack("nis"),
                         nis_dof=stack("nis_dof"), x0=stack("x0"), P0=stack("P0"),
                         series={name: np.stack([o.series[name] for o in rows])
                                 for name in blank.series})


_FAILURES = (EstimationError, np.linalg.LinAlgError, ArithmeticError)


def _run_stack(factory: Factory, runs: np.ndarray, Z: np.ndarray, dt: float | np.ndarray,
               U: np.ndarray | None, record: Mapping[str, Recorder] | None,
               before_step: Callable[[GaussianFilter, int], None] | None
               ) -> tuple[list[FilterOutput] | None, str | None]:
    """The outputs of runs `runs` stepped as one stack, one per run, or (None, why not):
    the factory builds no stack of them (a kind without `batched`, a factory that ignores
    the runs) or the stack failed."""
    try:
        filt = factory(runs)
    except (ValueError, TypeError, IndexError, *_FAILURES) as exc:
        # stepped one run at a time, which reports real errors
        return None, f"the stack could not be built: {_cause(exc)}"
    if not filt.batched or filt.x.shape[:-1] != (len(runs),):
        return None, "the factory builds no stack of runs"
    try:
        out = run_sequence(filt, Z[runs], dt, None if U is None else U[runs], record,
                           before_step)
    except _FAILURES as exc:
        return None, f"the stack failed at {_cause(exc)}"
    return [_run_of(out, i) for i in range(len(runs))], None


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


def _run_one(factory: Factory, r: int, Z: np.ndarray, dt: float | np.ndarray,
             U: np.ndarray | None, record: Mapping[str, Recorder] | None,
             before_step: Callable[[GaussianFilter, int], None] | None
             ) -> tuple[FilterOutput | None, int | None]:
    """Run r alone, its filter built for one track (`factory(r)`), and the state size of its
    filter; (None, ...) if it could not be built or failed."""
    try:
        filt = factory(r)
    except _FAILURES:
        return None, None
    try:
        out = run_sequence(filt, Z[r], dt, None if U is None else U[r], record, before_step)
    except _FAILURES:
        return None, filt.x.shape[-1]
    return out, filt.x.shape[-1]


def _run_of(out: FilterOutput, i: int) -> FilterOutput:
    """Run i of a stack's output, without the run axis."""
    return FilterOutput(x=out.x[i], P=out.P[i], nis=out.nis[i], nis_dof=out.nis_dof[i],
                        x0=out.x0[i], P0=out.P0[i],
                        series={name: a[i] for name, a in out.series.items()})


# ------------------------------------------------------------------------- statistics


def run_generators(seed: int, runs: int) -> list[tuple[np.random.Generator, np.random.Generator]]:
    """Per run, two independent streams from SeedSequence(seed).spawn(runs)[r].spawn(2):
    one for truth and measurements, one for anything the filter draws (e.g. x0-hat)."""
    out = []
    for child in np.random.SeedSequence(seed).spawn(runs):
        a, b = child.spawn(2)
        out.append((np.random.default_rng(a), np.random.default_rng(b)))
    return out


def squared_error(x: np.ndarray, truth: np.ndarray, components: slice) -> np.ndarray:
    """sum over `components` of (x - truth)^2, per run and step (R, K) (e.g. the squared
    position error with components = slice(0, 2))."""
    d = x[..., components] - truth[..., components]
    return np.sum(d * d, axis=-1)


def rmse(sq: np.ndarray) -> float:
    """Root of the mean over runs and steps of squared errors (R, K) (SEEDS 1.7)."""
    return float(np.sqrt(np.mean(sq)))


def run_rmse(sq: np.ndarray) -> np.ndarray:
    """Per-run RMSE sqrt(mean_k sq_rk) (R,): the values paired comparisons difference."""
    return np.sqrt(np.mean(sq, axis=1))


def nees_series(run: MonteCarloRun, truth: np.ndarray,
                residual: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
                ) -> np.ndarray:
    """NEES e' P^-1 e of the full state per run and step (R, K), e = truth - x (through
    `residual` for wrapped angles); NaN for failed runs and runs with a singular P."""
    out = np.full(truth.shape[:2], np.nan)
    for r in np.flatnonzero(~run.failed):
        e = truth[r] - run.x[r] if residual is None else residual(truth[r], run.x[r])
        try:
            out[r] = nees(e, run.P[r])
        except np.linalg.LinAlgError:   # a singular posterior covariance: no NEES for the run
            pass
    return out


def nees_summary(nees_rk: np.ndarray, dof: int) -> dict[str, float]:
    """nees (runs, steps): ANEES over runs and steps, the 95% band of the per-step average
    over the runs, and the fraction of steps whose run-average falls inside it (SEEDS 7.3)."""
    runs = nees_rk.shape[0]
    lo, hi = chi2_band(dof, runs)
    per_step = nees_rk.mean(axis=0)
    return {
        "anees": float(nees_rk.mean()),
        "anees_median_step": float(np.median(per_step)),
        "nees_band_lo": lo,
        "nees_band_hi": hi,
        "nees_steps_in_band": float(np.mean((per_step >= lo) & (per_step <= hi))),
    }


def nis_summary(nis: np.ndarray, dof: int) -> dict[str, float]:
    """nis (runs, steps) of updates with `dof` rows: the mean NIS (dof if consistent), the
    95% band of one run's time average and the fraction of runs inside it (SEEDS 7.3)."""
    lo, hi = chi2_band(dof, nis.shape[1])
    per_run = nis.mean(axis=1)
    return {"nis": float(nis.mean()), "nis_run_band_lo": lo, "nis_run_band_hi": hi,
            "nis_runs_in_band": float(np.mean((per_run >= lo) & (per_run <= hi)))}


def nis_consistency(nis: np.ndarray, dof: np.ndarray, level: float = 0.95
                    ) -> dict[str, object]:
    """The NIS test of one run (SEEDS 7.3). For a consistent filter the NIS of its updates
    are independent chi2(dof_k), so sum NIS / sum dof has the band chi2_band(1, sum dof).
    Returns the number of updates, that ratio (1 if consistent), its band, whether it is
    inside, and the fraction of updates above the upper (1 + level)/2 point of their own
    chi2(dof_k) ((1 - level)/2 if consistent). Undefined values are None (no updates)."""
    from scipy import stats

    used = np.asarray(dof) > 0
    D = int(np.sum(np.asarray(dof)[used]))
    out: dict[str, object] = {"updates": int(used.sum()), "nis_dof_sum": D, "level": level,
                              "nis_per_dof": None, "nis_per_dof_band": None,
                              "nis_consistent": None, "nis_fraction_above_upper": None}
    if D:
        ratio = float(np.sum(nis[used])) / D
        lo, hi = chi2_band(1, D, level)
        upper = stats.chi2.ppf(0.5 + level / 2, np.asarray(dof)[used])
        out.update(nis_per_dof=ratio, nis_per_dof_band=[lo, hi],
                   nis_consistent=bool(lo <= ratio <= hi),
                   nis_fraction_above_upper=float(np.mean(nis[used] > upper)))
    return out
