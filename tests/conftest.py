"""Shared fixtures: synthetic videos (rendered once per session), the real clips and an
in-process CLI runner."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_VIDEOS = ROOT.parent / "shared" / "videos"
HIGHWAY = SHARED_VIDEOS / "bgslibrary_video03_highway.avi"
RESIDENTIAL = SHARED_VIDEOS / "vehicle_counting_tf_sub-1504614469486_residential.mp4"


@pytest.fixture(scope="session")
def synth_video(tmp_path_factory):
    """Render (once) a synthetic clip per seed; returns a function seed -> folder."""
    from vtrack.sim.traffic import render_scene

    cache: dict[int, Path] = {}

    def make(seed: int, frames: int = 250, vehicles: int = 12) -> Path:
        key = (seed, frames, vehicles)
        if key not in cache:
            out = tmp_path_factory.mktemp(f"synth{seed}")
            render_scene(out, frames=frames, vehicles=vehicles, width=640, height=360, fps=25.0,
                         seed=seed)
            cache[key] = out
        return cache[key]

    return make


CLIPS = {"highway": HIGHWAY, "residential": RESIDENTIAL}


@pytest.fixture
def real_clip():
    """name -> path of a real clip in ../shared/videos (the test skips if it is absent)."""

    def get(name: str) -> Path:
        path = CLIPS[name]
        if not path.exists():
            pytest.skip(f"real clip not available: {path}")
        return path

    return get


@pytest.fixture
def cli_stdout():
    """args -> what `vtrack ARGS` prints on stdout, run in-process (it must exit 0)."""
    from vtrack.cli import main

    def run(args: list[str]) -> str:
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(args) == 0
        return buf.getvalue()

    return run
