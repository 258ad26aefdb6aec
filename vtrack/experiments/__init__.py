"""Seed-paper experiments, registered by name for `vtrack experiment NAME`.

Each experiment module calls `register(name, summary)` on a function
`run(runs: int, seed: int, batch: bool = True) -> ExperimentResult`; batch=False steps every
Monte Carlo run alone (the per-run loop that stepping the runs together replaces, for
benchmarks and checks). The result's `summary` is the JSON of
INTERFACE.md (`results` keyed by filter kind, further cases under `cases`); `example` holds one
Monte Carlo run's time series for plots and rerun.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class ExampleRun:
    """One run's series: times (T,), truth (T, n), per-filter estimates/covariances/NEES."""

    times: np.ndarray
    truth: np.ndarray
    estimates: dict[str, np.ndarray]
    covariances: dict[str, np.ndarray]
    nees: dict[str, np.ndarray] = field(default_factory=dict)
    sensors: np.ndarray | None = None          # (S, 2) fixed sensor positions, if any
    measurements: np.ndarray | None = None     # (T, m) raw measurements, if useful
    extra_series: dict[str, np.ndarray] = field(default_factory=dict)  # e.g. adapted R(t)
    position: tuple[int, int] = (0, 1)         # indices of x, y in the state


@dataclass
class ExperimentResult:
    summary: dict[str, Any]
    example: ExampleRun | None = None


Runner = Callable[..., ExperimentResult]   # run(runs, seed, batch=True)


@dataclass(frozen=True)
class Experiment:
    name: str
    summary: str
    run: Runner
    default_runs: int


EXPERIMENTS: dict[str, Experiment] = {}


def register(name: str, summary: str, default_runs: int = 100) -> Callable[[Runner], Runner]:
    """Register an experiment runner under `name`."""

    def deco(fn: Runner) -> Runner:
        EXPERIMENTS[name] = Experiment(name, summary, fn, default_runs)
        return fn

    return deco


def load_all() -> dict[str, Experiment]:
    """Import every experiment module (they register themselves) and return the registry."""
    for info in pkgutil.iter_modules(__path__):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__name__}.{info.name}")
    return EXPERIMENTS
