"""`vtrack filter`: one filter of the shared core over a recorded measurement log (INTERFACE.md).

This is the I/O edge around vtrack.estimation: it parses CONFIG.toml into a motion model, a
measurement model and a filter (`load_config`), reads MEASUREMENTS.csv (`read_measurements`),
runs the filter row by row through the Monte Carlo harness's run_sequence (`run_log`),
writes ESTIMATES.csv atomically (`write_estimates`) and, with --report, the NIS
consistency of the run (`consistency_report`). Every problem with the user's files is raised as InputError naming the
file (and the line or key), which the CLI prints as one `error:` line with exit code 2.

Timing convention (INTERFACE.md): (x0, P0) is the prior one step `dt` before the first row;
row k predicts over t_k - t_{k-1} (dt for the first row), then updates with the cells
present. For the unicycle, row k's inputs (u_v, u_omega) drive the prediction INTO row k,
i.e. they are the inputs applied over (t_{k-1}, t_k].
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vtrack.errors import InputError, MissingExtraError
from vtrack.estimation.filters import GaussianFilter
from vtrack.estimation.models import (
    Bearings,
    ConstantAcceleration,
    MeasurementModel,
    MotionModel,
    Ranges,
    Unicycle,
    WienerVelocity,
    pose_measurement,
    position_measurement,
)
from vtrack.estimation.montecarlo import FilterOutput, StepError, nis_consistency, run_sequence
from vtrack.fileio import open_input, read_toml, write_json
from vtrack.filter_kinds import make_filter

MOTION_MODELS = ("wiener-velocity", "constant-acceleration", "unicycle")
MEASUREMENT_MODELS = ("bearings", "position", "range", "pose")
UNICYCLE_INPUTS = ("u_v", "u_omega")
_UT_KEYS = ("alpha", "beta", "kappa")

_SECTION_KEYS = {
    "motion": {"model", "dt", "q"},
    "measurement": {"model", "sensors", "sigma"},
    "filter": {"kind"},  # + the options of the chosen kind (validated by make_filter)
    "init": {"x0", "P0"},
}


# ------------------------------------------------------------------------------ config


@dataclass
class FilterConfig:
    """A parsed CONFIG.toml: the models, the filter kind and options, and the prior."""

    path: str
    motion_model: str
    dt: float
    measurement_model: str
    kind: str
    options: dict[str, Any]
    x0: np.ndarray
    P0: np.ndarray
    motion: MotionModel
    measurement: MeasurementModel
    sensors: np.ndarray | None = None
    toml: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """State dimension."""
        return int(self.motion.n)

    @property
    def m(self) -> int:
        """Number of measurement columns z0..z{m-1}."""
        return int(self.measurement.m)

    @property
    def input_columns(self) -> tuple[str, ...]:
        """Control-input columns that follow the measurements (unicycle only)."""
        return UNICYCLE_INPUTS if self.motion_model == "unicycle" else ()

    def csv_header(self) -> list[str]:
        """The MEASUREMENTS.csv header these models expect."""
        return ["t"] + [f"z{i}" for i in range(self.m)] + list(self.input_columns)

    def estimates_header(self) -> list[str]:
        """ESTIMATES.csv header: t, the mean, the covariance row-major."""
        n = self.n
        return (["t"] + [f"x{i}" for i in range(n)]
                + [f"P{i}_{j}" for i in range(n) for j in range(n)])

    def build_filter(self) -> GaussianFilter:
        """A fresh filter at the prior (x0, P0)."""
        return make_filter(self.kind, self.motion, self.measurement, self.x0.copy(),
                           self.P0.copy(), **self.options)


class _Section:
    """Typed access to one TOML table, with errors that name the file, section and key."""

    def __init__(self, path: str, name: str, table: Any) -> None:
        self.path, self.name = path, name
        if not isinstance(table, dict):
            self.fail(f"must be a table ([{name}])")
        self.table: dict[str, Any] = table

    def fail(self, msg: str, key: str | None = None) -> None:
        where = f"[{self.name}]" + (f" {key}" if key else "")
        raise InputError(f"{self.path}: {where}: {msg}")

    def check_keys(self, allowed: set[str]) -> None:
        for key in self.table:
            if key not in allowed:
                self.fail(f"unknown key {key!r} (known: {', '.join(sorted(allowed))})")

    def get(self, key: str) -> Any:
        if key not in self.table:
            self.fail(f"missing required key {key!r}")
        return self.table[key]

    def string(self, key: str, choices: tuple[str, ...] | None = None,
               what: str = "value") -> str:
        val = self.get(key)
        if not isinstance(val, str):
            self.fail(f"must be a string, got {val!r}", key)
        if choices is not None and val not in choices:
            self.fail(f"unknown {what} {val!r} (known: {', '.join(choices)})", key)
        return val

    def number(self, key: str, *, positive: bool = False, nonneg: bool = False,
               value: Any = None, label: str | None = None) -> float:
        val = self.get(key) if value is None else value
        label = label or key
        if isinstance(val, bool) or not isinstance(val, (int, float)):
            self.fail(f"must be a number, got {val!r}", label)
        x = float(val)
        if not math.isfinite(x):
            self.fail(f"must be finite, got {val!r}", label)
        if positive and x <= 0:
            self.fail(f"must be > 0, got {val!r}", label)
        if nonneg and x < 0:
            self.fail(f"must be >= 0, got {val!r}", label)
        return x

    def vector(self, key: str, length: int, *, positive: bool = False, nonneg: bool = False,
               allow_scalar: bool = False, value: Any = None) -> np.ndarray | float:
        val = self.get(key) if value is None else value
        if allow_scalar and not isinstance(val, list):
            return self.number(key, positive=positive, nonneg=nonneg, value=val)
        if not isinstance(val, list) or len(val) != length:
            self.fail(f"must be {'a number or ' if allow_scalar else ''}a list of {length} "
                      f"numbers, got {val!r}", key)
        return np.array([self.number(key, positive=positive, nonneg=nonneg, value=v,
                                     label=f"{key}[{i}]") for i, v in enumerate(val)])


def load_config(path: str | os.PathLike) -> FilterConfig:
    """Parse CONFIG.toml (INTERFACE.md `vtrack filter`) and validate it completely.

    The filter is built once here so that an unknown kind or option, a model the kind cannot
    handle, or a P0 that is not positive definite is reported against the config file
    before any measurement is read."""
    path = str(path)
    return config_from_dict(read_toml(path), path)


def config_from_dict(doc: dict[str, Any], path: str = "<config>") -> FilterConfig:
    """Validate a parsed TOML document (as `load_config` does) and build the models."""
    for name in doc:
        if name not in _SECTION_KEYS:
            raise InputError(f"{path}: unknown section or key {name!r} "
                             f"(known sections: {', '.join(_SECTION_KEYS)})")
    for name in _SECTION_KEYS:
        if name not in doc:
            raise InputError(f"{path}: missing section [{name}]")

    # [motion]
    sec = _Section(path, "motion", doc["motion"])
    sec.check_keys(_SECTION_KEYS["motion"])
    mname = sec.string("model", MOTION_MODELS, "motion model")
    dt = sec.number("dt", positive=True)
    motion: MotionModel
    if mname == "unicycle":
        q = sec.vector("q", 3, nonneg=True, allow_scalar=True)
        motion = Unicycle(q)
    else:
        q = sec.number("q", nonneg=True)
        motion = WienerVelocity(q) if mname == "wiener-velocity" else ConstantAcceleration(q)
    n = motion.n

    # [measurement]
    sec = _Section(path, "measurement", doc["measurement"])
    zname = sec.string("model", MEASUREMENT_MODELS, "measurement model")
    sensors = None
    if zname in ("bearings", "range"):
        sec.check_keys(_SECTION_KEYS["measurement"])
        raw = sec.get("sensors")
        if not isinstance(raw, list) or not raw:
            sec.fail(f"must be a non-empty list of [x, y] pairs, got {raw!r}", "sensors")
        for i, s in enumerate(raw):
            if not isinstance(s, list) or len(s) != 2:
                sec.fail(f"sensor {i} must be an [x, y] pair, got {s!r}", "sensors")
        sensors = np.array([[sec.number("sensors", value=v, label=f"sensors[{i}]") for v in s]
                            for i, s in enumerate(raw)], dtype=float)
        m = len(sensors)
    else:
        sec.check_keys(_SECTION_KEYS["measurement"] - {"sensors"})
        m = 3 if zname == "pose" else 2
    sigma = sec.vector("sigma", m, positive=True, allow_scalar=True)
    measurement: MeasurementModel
    if zname == "bearings":
        measurement = Bearings(sensors, sigma, n=n)
    elif zname == "range":
        measurement = Ranges(sensors, sigma, n=n)
    elif zname == "position":
        measurement = position_measurement(n, sigma)
    else:
        if mname != "unicycle":
            sec.fail(f"measurement model 'pose' measures (x, y, heading) and needs motion "
                     f"model 'unicycle', not {mname!r}", "model")
        measurement = pose_measurement(sigma)

    # [init]
    sec = _Section(path, "init", doc["init"])
    sec.check_keys(_SECTION_KEYS["init"])
    x0 = sec.vector("x0", n)
    P0 = _parse_P0(sec, n)

    # [filter]
    sec = _Section(path, "filter", doc["filter"])
    kind = sec.string("kind")
    options = {k: v for k, v in sec.table.items() if k != "kind"}
    for key in _UT_KEYS:
        if key in options:
            options[key] = sec.number(key)
    try:
        make_filter(kind, motion, measurement, x0.copy(), P0.copy(), **options)
    except (ValueError, TypeError) as exc:  # EstimationError is a ValueError
        sec.fail(" ".join(str(exc).split()))

    return FilterConfig(path=path, motion_model=mname, dt=dt, measurement_model=zname,
                        kind=kind, options=options, x0=x0, P0=P0, motion=motion,
                        measurement=measurement, sensors=sensors, toml=doc)


def _parse_P0(sec: _Section, n: int) -> np.ndarray:
    """P0: a list of n variances (the diagonal) or n rows of n numbers; symmetric, PD."""
    raw = sec.get("P0")
    shape_msg = (f"must be a list of {n} variances (the diagonal) or a {n}x{n} matrix as a "
                 f"list of {n} rows")
    if not isinstance(raw, list) or len(raw) != n:
        sec.fail(f"{shape_msg}, got {raw!r}", "P0")
    if all(isinstance(r, list) for r in raw):
        rows = []
        for i, r in enumerate(raw):
            if len(r) != n:
                sec.fail(f"{shape_msg}; row {i} has {len(r)} entries", "P0")
            rows.append([sec.number("P0", value=v, label=f"P0[{i}][{j}]")
                         for j, v in enumerate(r)])
        P0 = np.array(rows)
        if not np.allclose(P0, P0.T, rtol=1e-12, atol=1e-12 * np.abs(P0).max()):
            sec.fail("must be symmetric", "P0")
    elif any(isinstance(r, list) for r in raw):
        sec.fail(f"{shape_msg} (mixes numbers and rows)", "P0")
    else:
        P0 = np.diag([sec.number("P0", value=v, positive=True, label=f"P0[{i}]")
                      for i, v in enumerate(raw)])
    try:
        np.linalg.cholesky(0.5 * (P0 + P0.T))
    except np.linalg.LinAlgError:
        sec.fail(f"must be positive definite (smallest eigenvalue "
                 f"{np.linalg.eigvalsh(0.5 * (P0 + P0.T)).min():.3g})", "P0")
    return P0


# ------------------------------------------------------------------------ measurements


@dataclass
class Measurements:
    """MEASUREMENTS.csv as arrays: times (K,), z (K, m) with NaN = missing, inputs (K, 2) or
    None, and the 1-based file line of each row (for error messages)."""

    path: str
    t: np.ndarray
    z: np.ndarray
    u: np.ndarray | None
    lines: list[int]


def _cell(path: str, line: int, col: str, text: str, missing_ok: bool) -> float:
    s = text.strip()
    if s == "":
        if missing_ok:
            return math.nan
        raise InputError(f"{path}: line {line}: column {col} is empty (a value is required)")
    try:
        val = float(s)
    except ValueError:
        raise InputError(f"{path}: line {line}: column {col}: not a number: {s!r}") from None
    if math.isinf(val):
        raise InputError(f"{path}: line {line}: column {col}: infinite value {s!r} "
                         "(use an empty cell or nan for a missing measurement)")
    if math.isnan(val) and not missing_ok:
        raise InputError(f"{path}: line {line}: column {col} is nan (a value is required)")
    return val


def read_measurements(path: str | os.PathLike, cfg: FilterConfig) -> Measurements:
    """Read and validate MEASUREMENTS.csv against the config's models (INTERFACE.md).

    Header `t,z0,...,z{m-1}` (+ `u_v,u_omega` for the unicycle); t finite and strictly
    increasing; a z cell that is empty or nan is missing; inf, text or a wrong number of cells
    is an InputError naming the file and line. Blank lines are skipped."""
    path = str(path)
    expected = cfg.csv_header()
    m = cfg.m
    fh = open_input(path, "CSV file", newline="", encoding="utf-8-sig")
    t: list[float] = []
    z: list[list[float]] = []
    u: list[list[float]] = []
    lines: list[int] = []
    try:
        with fh:
            reader = csv.reader(fh)
            header = None
            for row in reader:
                line = reader.line_num
                if not row:
                    continue
                if header is None:
                    header = [c.strip() for c in row]
                    if header != expected:
                        nz = sum(1 for c in header if c.startswith("z"))
                        raise InputError(
                            f"{path}: line {line}: header {','.join(header)!r} does not match "
                            f"the config ({cfg.measurement_model} measurement model with {m} "
                            f"measurement(s), {cfg.motion_model} motion; found {nz} z "
                            f"column(s)); expected {','.join(expected)!r}")
                    continue
                if len(row) != len(expected):
                    raise InputError(f"{path}: line {line}: {len(row)} cells, expected "
                                     f"{len(expected)} ({','.join(expected)})")
                tk = _cell(path, line, "t", row[0], missing_ok=False)
                if t and not tk > t[-1]:
                    raise InputError(f"{path}: line {line}: t = {row[0].strip()} is not "
                                     f"greater than the previous t = {t[-1]!r} "
                                     "(t must be strictly increasing)")
                t.append(tk)
                z.append([_cell(path, line, expected[1 + i], row[1 + i], missing_ok=True)
                          for i in range(m)])
                u.append([_cell(path, line, expected[1 + m + i], row[1 + m + i],
                                missing_ok=False) for i in range(len(cfg.input_columns))])
                lines.append(line)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text ({exc.reason})") from None
    except csv.Error as exc:
        raise InputError(f"{path}: malformed CSV: {exc}") from None
    if header is None:
        raise InputError(f"{path}: empty file (expected the header {','.join(expected)!r})")
    K = len(t)
    return Measurements(
        path=path, t=np.array(t, dtype=float), z=np.array(z, dtype=float).reshape(K, m),
        u=np.array(u, dtype=float).reshape(K, len(cfg.input_columns))
        if cfg.input_columns else None,
        lines=lines)


# -------------------------------------------------------------------------------- run


def run_log(filt: GaussianFilter, meas: Measurements, dt0: float) -> FilterOutput:
    """Run `filt` over the log's rows (the harness's run_sequence): row k predicts over
    t_k - t_{k-1} (dt0 for the first row) with its inputs, then updates with the finite
    cells of z_k (an all-missing row only predicts). Any estimation failure (non-PD
    covariance, overflow, non-finite posterior) is an InputError naming the file's line."""
    dts = np.diff(meas.t, prepend=meas.t[0] - dt0) if len(meas.t) else np.empty(0)
    try:
        return run_sequence(filt, meas.z, dts, meas.u, require_finite=True)
    except StepError as exc:
        raise InputError(f"{meas.path}: line {meas.lines[exc.step]} (t = "
                         f"{float(meas.t[exc.step])!r}): filter {filt.kind!r} failed: "
                         f"{exc.cause}") from None


def estimates_rows(t: np.ndarray, xs: np.ndarray, Ps: np.ndarray) -> list[list[str]]:
    """ESTIMATES.csv rows at full precision (repr of each float, which round-trips)."""
    flat = np.concatenate([t[:, None], xs, Ps.reshape(len(t), xs.shape[1] ** 2)], axis=1)
    return [[repr(float(v)) for v in row] for row in flat]


def write_estimates(path: str | os.PathLike, cfg: FilterConfig, t: np.ndarray,
                    xs: np.ndarray, Ps: np.ndarray) -> None:
    """Write ESTIMATES.csv atomically (nothing is left under `path` if this fails)."""
    from vtrack.fileio import write_csv

    try:
        write_csv(path, estimates_rows(t, xs, Ps), header=cfg.estimates_header())
    except OSError as exc:
        raise InputError(f"{path}: cannot write: {exc.strerror or exc}") from None


def _rerun_logger():  # noqa: ANN202
    """Import vtrack.viz.rerun_log lazily (only for --rerun)."""
    try:
        from vtrack.viz import rerun_log
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] == "rerun":
            raise MissingExtraError("rerun", "rerun-sdk") from None
        raise InputError("--rerun: rerun logging is not available in this build "
                         f"({exc.name} is missing)") from None
    return rerun_log.log_filter_run


def consistency_report(cfg: FilterConfig, meas: Measurements, out: FilterOutput
                       ) -> dict[str, Any]:
    """The --report JSON: the filter, the rows and updates, and the NIS test of the run
    (montecarlo.nis_consistency)."""
    return {"config": cfg.path, "measurements": meas.path, "kind": cfg.kind,
            "options": cfg.options, "rows": len(meas.t),
            **nis_consistency(out.nis, out.nis_dof)}


def filter_files(config: str, measurements: str, out: str, rerun: str | None = None,
                 report: str | None = None) -> int:
    """`vtrack filter CONFIG.toml MEASUREMENTS.csv --out ESTIMATES.csv [--rerun FILE.rrd]
    [--report REPORT.json]`.

    Everything is validated and computed before anything is written, so on any error no
    ESTIMATES.csv is created (or an existing one is left untouched)."""
    log = _rerun_logger() if rerun else None
    cfg = load_config(config)
    meas = read_measurements(measurements, cfg)
    run = run_log(cfg.build_filter(), meas, cfg.dt)
    if log is not None:
        log(meas.t, run.x, run.P, meas.z, cfg.sensors, rerun)
    write_estimates(out, cfg, meas.t, run.x, run.P)
    if report is not None:
        try:
            write_json(report, consistency_report(cfg, meas, run))
        except OSError as exc:
            raise InputError(f"{report}: cannot write: {exc.strerror or exc}") from None
    return 0
