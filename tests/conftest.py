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


@pytest.fixture(scope="session")
def overhead_truth():
    """(seed, folder) -> writes folder/calibration.toml and folder/world.csv for the
    synth_video fixture's scene of that seed: the overhead view is a pure scale (pixels /
    px_per_m); world.csv has each vehicle's speed, length and class per frame."""
    import numpy as np

    from vtrack.sim.traffic import simulate_traffic

    def write(seed: int, folder: Path, frames: int = 250, vehicles: int = 12) -> Path:
        tr = simulate_traffic(frames, vehicles, 640, 360, 25.0, seed)
        ppm = tr.layout.px_per_m
        pts = [(40, 60), (600, 70), (590, 330), (50, 320)]
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "calibration.toml").write_text("frame_size = [640, 360]\n" + "".join(
            f"[[points]]\nimage = [{u}, {v}]\nworld = [{u / ppm:.6f}, {v / ppm:.6f}]\n"
            for u, v in pts))
        rows = ["frame,id,X_m,Y_m,speed_kmh,length_m,class"]
        for k, veh in enumerate(tr.vehicles):
            for n in np.flatnonzero(np.isfinite(tr.s[k])):
                rows.append(f"{n + 1},{veh.id},{tr.s[k, n] / ppm:.3f},0,"
                            f"{3.6 * tr.v[k, n] / ppm:.3f},{veh.length / ppm:.3f},{veh.kind}")
        (folder / "world.csv").write_text("\n".join(rows) + "\n")
        return folder / "calibration.toml"

    return write


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
