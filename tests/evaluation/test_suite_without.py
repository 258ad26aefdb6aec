"""scripts/eval_suite.py --without: a perspective clip rendered without one nuisance keeps
its vehicles and their boxes (each nuisance draws from its own random stream), so the
suite's score without it is what handling that phenomenon perfectly would be worth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtrack.io.video import VideoReader


def _frames(video: Path) -> np.ndarray:
    with VideoReader(video) as reader:
        return np.stack([frame.image for frame in reader])


def test_without_shadows_keeps_the_vehicles_and_changes_the_pixels(tmp_path, load_script):
    suite = load_script("eval_suite")
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


def test_without_rejects_an_unknown_nuisance(capsys, load_script):
    with pytest.raises(SystemExit) as exc:
        load_script("eval_suite").main(["--without", "fog", "--no-real"])
    assert exc.value.code == 2
    assert "unknown nuisance 'fog'" in capsys.readouterr().err
