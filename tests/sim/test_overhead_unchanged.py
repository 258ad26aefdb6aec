"""The overhead scene (`vtrack synth`'s default) stays byte-identical to the code before the
scene presets existed: sha256 of gt.csv and of the raw frames (before MJPG encoding, which
depends on the OpenCV build) were recorded from commit a7d84d5 (main before issue 11)."""

from __future__ import annotations

import hashlib

import pytest

from vtrack.cli import main
from vtrack.sim.traffic import Renderer, simulate_traffic

GT_SHA256 = [
    (["--frames", "40", "--vehicles", "6", "--width", "320", "--height", "180", "--seed", "0"],
     "f460ef85cfc94d44912368ad831520a0f2c985fd6b08e15a7a5e9fc8387a7562"),
    (["--frames", "60", "--vehicles", "10", "--width", "320", "--height", "180", "--seed", "5"],
     "75f55054927047c1a5b82ff265f71c5f87e9d6145997835a697e0b7b70c71d28"),
    (["--frames", "30", "--vehicles", "4", "--width", "200", "--height", "120", "--seed", "2"],
     "c32f1fd79358c4ab50a45ade64239589758ddf9ddae935d9b89739e5d2b05a63"),
]

FRAMES_SHA256 = [
    ((40, 6, 320, 180, 0), "17d07e8805a22185d4a0a76f197692f3f35dfac80f023f2894afc56dea48eff3"),
    ((30, 4, 200, 120, 2), "87ec5d413e8d466661ff9cedec69cea200ca5ce78fc9d2932397caca9373bf28"),
]


@pytest.mark.parametrize(("args", "digest"), GT_SHA256)
def test_overhead_gt_bytes_unchanged(tmp_path, capsys, args, digest):
    assert main(["synth", str(tmp_path), *args]) == 0
    assert hashlib.sha256((tmp_path / "gt.csv").read_bytes()).hexdigest() == digest


@pytest.mark.parametrize(("case", "digest"), FRAMES_SHA256)
def test_overhead_frames_unchanged(case, digest):
    frames, vehicles, width, height, seed = case
    traj = simulate_traffic(frames, vehicles, width, height, 25.0, seed)
    sha = hashlib.sha256()
    for frame in Renderer(traj, seed).frames():
        sha.update(frame.tobytes())
    assert sha.hexdigest() == digest
