"""Small Monte Carlo helpers shared by the robot, fuzzy and siim experiments (SEEDS 1.7)."""

from __future__ import annotations


import numpy as np

from vtrack.estimation.bounds import chi2_band


def run_generators(seed: int, runs: int) -> list[tuple[np.random.Generator, np.random.Generator]]:
    """Per run, two independent streams from SeedSequence(seed).spawn(runs)[r].spawn(2):
    one for truth and measurements, one for anything the filter draws (e.g. x0-hat)."""
    out = []
    for child in np.random.SeedSequence(seed).spawn(runs):
        a, b = child.spawn(2)
        out.append((np.random.default_rng(a), np.random.default_rng(b)))
    return out


def rms(a: np.ndarray) -> float:
    """Root of the mean of squares over every entry."""
    return float(np.sqrt(np.mean(np.square(a))))


def nees_summary(nees: np.ndarray, dof: int) -> dict[str, float]:
    """nees (runs, steps): ANEES over runs and steps, the 95% band of the per-step average
    over the runs, and the fraction of steps whose run-average falls inside it (SEEDS 7.3)."""
    runs = nees.shape[0]
    lo, hi = chi2_band(dof, runs)
    per_step = nees.mean(axis=0)
    return {
        "anees": float(nees.mean()),
        "anees_median_step": float(np.median(per_step)),
        "nees_band_lo": lo,
        "nees_band_hi": hi,
        "nees_steps_in_band": float(np.mean((per_step >= lo) & (per_step <= hi))),
    }


