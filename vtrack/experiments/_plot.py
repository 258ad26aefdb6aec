"""`vtrack experiment NAME --plot FILE.png`: one figure for any experiment, from result.example.

Panels (those without data are left out):

1. x-y: the truth, each filter's estimate and the fixed sensors (ExampleRun.sensors);
2. position error vs time: each filter's error in the example run (thin); Monte Carlo
   per-step RMSE curves from extra_series `rmse/<kind>` (thick) and the per-step bound
   `pcrlb` (dashed), when the experiment provides them;
3. NEES vs time: the run-averaged NEES `nees/<kind>` from extra_series with the band
   summary["nees_band"] = [lo, hi] when both are present; otherwise the example run's NEES
   (ExampleRun.nees) with the single-run 95% chi2(n) band;
4. every other extra series (e.g. `R_used/<kind>`, `lambda_P/<kind>`), one axis each.

matplotlib is the optional extra `plot`; the Agg backend is used and the file is written
atomically (temporary sibling, then os.replace).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from vtrack.errors import InputError, MissingExtraError
from vtrack.experiments import ExampleRun, ExperimentResult


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise MissingExtraError("plot", "matplotlib") from None
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _split_extra(ex: ExampleRun) -> tuple[dict, dict, np.ndarray | None, dict]:
    rmse, nees_avg, other = {}, {}, {}
    bound = None
    for key, series in ex.extra_series.items():
        if key.startswith("rmse/"):
            rmse[key[5:]] = series
        elif key.startswith("nees/"):
            nees_avg[key[5:]] = series
        elif key == "pcrlb":
            bound = series
        else:
            other[key] = series
    return rmse, nees_avg, bound, other


def save_plot(result: ExperimentResult, name: str, path: str) -> None:
    """Draw result.example (see the module docstring) into the PNG `path`, atomically."""
    ex = result.example
    if ex is None:
        raise InputError(f"experiment {name!r} has no example run to plot")
    plt = _pyplot()
    from scipy import stats

    rmse, nees_avg, bound, other = _split_extra(ex)
    t = np.asarray(ex.times, dtype=float)
    ix, iy = ex.position
    kinds = list(ex.estimates)
    colors = {k: f"C{i}" for i, k in enumerate(kinds)}
    styles = {k: ("-", "--", ":", "-.")[i % 4] for i, k in enumerate(kinds)}  # overlaps show

    panels = ["xy", "err"]
    if nees_avg or ex.nees:
        panels.append("nees")
    panels += list(other)
    ncols = 2
    nrows = (len(panels) + 1) // 2
    fig, axes = plt.subplots(nrows, ncols, figsize=(12, 4.2 * nrows), squeeze=False)
    flat = list(axes.ravel())
    for ax in flat[len(panels):]:
        ax.set_visible(False)

    ax = flat[0]
    ax.plot(ex.truth[:, ix], ex.truth[:, iy], "k-", lw=2.0, label="truth")
    for k in kinds:
        ax.plot(ex.estimates[k][:, ix], ex.estimates[k][:, iy], styles[k], color=colors[k],
                lw=1.2, label=k)
    if ex.sensors is not None and len(ex.sensors):
        s = np.asarray(ex.sensors)
        ax.plot(s[:, 0], s[:, 1], "k^", ms=9, label="sensors")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"{name}: example run")
    ax.legend(fontsize=8)

    ax = flat[1]
    for k in kinds:
        d = ex.estimates[k][:, [ix, iy]] - ex.truth[:, [ix, iy]]
        ax.plot(t, np.hypot(d[:, 0], d[:, 1]), "-", color=colors[k], lw=0.6, alpha=0.5,
                label=f"{k} (example run)")
        if k in rmse:
            ax.plot(t, rmse[k], styles[k], color=colors[k], lw=2.0,
                    label=f"{k} RMSE over runs")
    if bound is not None:
        ax.plot(t, bound, "k--", lw=1.5, label="PCRLB")
    ax.set_xlabel("time")
    ax.set_ylabel("position error")
    ax.set_title("position error")
    ax.legend(fontsize=7)

    if "nees" in panels:
        ax = flat[2]
        n = ex.truth.shape[1]
        band = result.summary.get("nees_band")
        if nees_avg and band is not None:
            series, lo, hi = nees_avg, band[0], band[1]
            label = "NEES averaged over runs"
        else:
            series = ex.nees
            lo, hi = stats.chi2.ppf([0.025, 0.975], n)
            label = "NEES (example run)"
        for k, v in series.items():
            ax.plot(t[: len(v)], v, styles.get(k, "-"), color=colors.get(k), lw=1.2, label=k)
        ax.axhspan(lo, hi, color="0.8", alpha=0.6, label="95% chi2 band")
        ax.axhline(n, color="k", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_xlabel("time")
        ax.set_ylabel("NEES")
        ax.set_title(label)
        ax.legend(fontsize=7)

    for key, ax in zip(other, flat[len(panels) - len(other): len(panels)]):
        v = np.asarray(other[key], dtype=float)
        if v.ndim == 1:
            v = v[:, None]
        v = v.reshape(len(v), -1)
        for j in range(v.shape[1]):
            ax.plot(t[: len(v)], v[:, j], "-", lw=1.0,
                    label=f"component {j}" if v.shape[1] > 1 else None)
        ax.set_xlabel("time")
        ax.set_title(key)
        if v.shape[1] > 1:
            ax.legend(fontsize=7)

    fig.tight_layout()
    try:
        _write_atomically(fig, Path(path))
    except OSError as exc:
        raise InputError(f"cannot write plot {path}: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)


def _write_atomically(fig, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".png", dir=target.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=110, format="png")
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
