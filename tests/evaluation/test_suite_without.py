"""scripts/eval_suite.py --without: a perspective clip rendered without one nuisance keeps
its vehicles and their boxes (each nuisance draws from its own random stream), so the
suite's score without it is what handling that phenomenon perfectly would be worth."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from vtrack.vision.video import VideoReader

ROOT = Path(__file__).resolve().parents[2]


def _suite():
    spec = importlib.util.spec_from_file_location("eval_suite", ROOT / "scripts/eval_suite.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod   # its dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def _frames(video: Path) -> np.ndarray:
    with VideoReader(video) as reader:
        return np.stack([frame.image for frame in reader])


def test_without_shadows_keeps_the_vehicles_and_changes_the_pixels(tmp_path):
    suite = _suite()
    base = suite.render(suite.SynthClip("mast", 0, 12), tmp_path)
    bare = suite.render(suite.SynthClip("mast", 0, 12, without=("shadows",)), tmp_path)
    assert base != bare and base.name.startswith("mast-0-") and bare.name.startswith("mast-0-")
    truth, truth_bare = (np.loadtxt(p / "gt.csv", delimiter=",", ndmin=2) for p in (base, bare))
    np.testing.assert_array_equal(truth[:, :6], truth_bare[:, :6])   # same vehicles, same boxes
    a, b = _frames(base / "video.avi"), _frames(bare / "video.avi")
    assert a.shape == b.shape
    # The cast shadows darken the picture where they fall: without them it is brighter.
    changed = np.abs(a.astype(int) - b.astype(int)).max(axis=3) > 40
    assert changed.mean() > 0.01
    assert b.astype(float)[changed].mean() > a.astype(float)[changed].mean()


def test_without_rejects_an_unknown_nuisance(capsys):
    with pytest.raises(SystemExit) as exc:
        _suite().main(["--without", "fog", "--no-real"])
    assert exc.value.code == 2
    assert "unknown nuisance 'fog'" in capsys.readouterr().err
