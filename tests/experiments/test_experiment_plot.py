"""vtrack.experiments._plot.save_plot: generic over ExampleRun contents, atomic, optional extra."""

import sys

import numpy as np
import pytest

from vtrack.errors import InputError, MissingExtraError
from vtrack.experiments import ExampleRun, ExperimentResult
from vtrack.experiments._plot import save_plot

PNG = b"\x89PNG\r\n\x1a\n"


def _result(extra=True, sensors=True, summary_band=True):
    t = np.linspace(0.01, 1.0, 100)
    truth = np.stack([t, t**2, np.ones_like(t), 2 * t], axis=1)
    est = {"ekf": truth + 0.01, "ukf": truth - 0.01}
    cov = {k: np.broadcast_to(np.eye(4) * 1e-4, (100, 4, 4)) for k in est}
    ex = ExampleRun(times=t, truth=truth, estimates=est, covariances=cov,
                    nees={k: np.full(100, 4.0) for k in est},
                    sensors=np.array([[0.0, -1.0], [1.0, 2.0]]) if sensors else None)
    if extra:
        ex.extra_series = {"rmse/ekf": np.full(100, 0.014), "pcrlb": np.full(100, 0.01),
                           "nees/ekf": np.full(100, 4.1), "R_used/ekf": np.ones((100, 2))}
    summary = {"results": {}, "nees_band": [3.4, 4.6]} if summary_band else {"results": {}}
    return ExperimentResult(summary, ex)


@pytest.mark.parametrize("kw", [{}, {"extra": False, "sensors": False, "summary_band": False}])
def test_save_plot_writes_a_png_atomically(tmp_path, kw):
    out = tmp_path / "sub" / "fig.png"
    save_plot(_result(**kw), "demo", str(out))
    assert out.read_bytes()[:8] == PNG
    assert [p.name for p in out.parent.iterdir()] == ["fig.png"]


def test_save_plot_without_example_is_an_input_error(tmp_path):
    with pytest.raises(InputError):
        save_plot(ExperimentResult({"results": {}}, None), "demo", str(tmp_path / "x.png"))


def test_save_plot_into_an_unwritable_place_is_an_input_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(InputError):
        save_plot(_result(), "demo", str(blocker / "x.png"))


def test_missing_matplotlib_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)     # import matplotlib -> ImportError
    with pytest.raises(MissingExtraError, match=r"vtrack\[plot\]"):
        save_plot(_result(), "demo", str(tmp_path / "x.png"))
    assert not (tmp_path / "x.png").exists()
