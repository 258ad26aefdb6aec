"""Tracked fps divided by decode-only fps on a 1280x720 MJPG video from `vtrack synth`,
measured in one run. Start-up (process spawn, model set-up) is excluded by subtracting a
one-frame run from each timing.

    .venv/bin/python scripts/bench_pipeline.py [--frames 300] [--config CFG.toml]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from vtrack.app import config
from vtrack.sim.traffic import render_scene
from vtrack.app.track import TrackOptions, track_video
from vtrack.vision.video import VideoReader


def _decode(video: Path, frames: int) -> float:
    t0 = time.perf_counter()
    with VideoReader(video, max_frames=frames) as reader:
        for _ in reader:
            pass
    return time.perf_counter() - t0


def _track(video: Path, out: Path, cfg: config.AppConfig, frames: int) -> float:
    t0 = time.perf_counter()
    track_video(video, out, cfg, TrackOptions(max_frames=frames))
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--config", help="TOML config for the tracked run (default config if absent)")
    args = ap.parse_args()
    cfg = config.load(args.config)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        render_scene(tmp / "synth", frames=args.frames, vehicles=20, width=1280, height=720,
                     fps=25.0, seed=0)
        video = tmp / "synth" / "video.avi"
        n = args.frames - 1
        decode = _decode(video, args.frames) - _decode(video, 1)
        track = _track(video, tmp / "out", cfg, args.frames) - _track(video, tmp / "o1", cfg, 1)
    print(f"video: 1280x720 MJPG (vtrack synth), {args.frames} frames; "
          f"detect_width {cfg.detector.detect_width}")
    print(f"decode only : {n / decode:8.1f} fps")
    print(f"tracked     : {n / track:8.1f} fps")
    print(f"ratio tracked/decode: {decode / track:.3f}")


if __name__ == "__main__":
    main()
