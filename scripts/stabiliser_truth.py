#!/usr/bin/env python3
"""How far the detector's stabiliser is from the true camera sway, on synthetic clips.

The renderer knows the sway (`ClipRenderer.shake`: frame n is cut out of the canvas at that
offset, so a static point moves by -shake[n]); the detector's stabiliser estimates M,
reference -> frame. Per clip and stabiliser setting this prints the error of M's shift at
the image centre against -shake[n], in full-resolution pixels, after removing one constant
offset (the reference -- the first frame, or with `stabilise_robust` the background
estimated from the video -- sits at an unknown mean position): the mean over all frames,
over the first 20 and the worst frame. Clips are rendered (or reused) like the scene suite's.

    .venv/bin/python scripts/stabiliser_truth.py                  # mast, side, junction x 3
    .venv/bin/python scripts/stabiliser_truth.py --only side-1
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_suite import SynthClip, render  # noqa: E402  (a sibling script)


def true_shift(clip: SynthClip) -> np.ndarray:
    """(frames, 2) the image motion of a static point in frame n: -shake[n]."""
    from vtrack.sim.clip import ClipRenderer, build_scene
    from vtrack.sim.nuisance import parse_nuisances

    scene = build_scene(clip.scene, clip.frames, None, clip.width, clip.height, 25.0,
                        clip.seed, parse_nuisances("all"))
    return -ClipRenderer(scene, clip.seed).shake


def estimated_shift(video: Path, robust: bool) -> np.ndarray:
    """(frames, 2) the detector's estimate of the same motion: M (reference -> frame, full
    resolution) applied to the image centre, minus the centre; the run as `vtrack track`
    starts it (background samples from the first seconds, then every frame)."""
    from vtrack.vision.detect import DetectorConfig, MotionDetector
    from vtrack.io.video import VideoReader

    cfg = dataclasses.replace(DetectorConfig(), stabilise_robust=robust)
    with VideoReader(str(video)) as reader:
        info = reader.info
        frames = [f.image for f in reader]
    detector = MotionDetector(cfg, info.width, info.height, info.fps)
    n = min(round(cfg.init_background_seconds * info.fps), len(frames))
    stride = n / cfg.init_background_samples
    detector.initialise(frames[int(k * stride)] for k in range(cfg.init_background_samples))
    centre = np.array([info.width / 2, info.height / 2, 1.0])
    out = []
    for image in frames:
        m = detector.segment(image).camera
        out.append(m @ centre - centre[:2])
    return np.array(out)


def errors(est: np.ndarray, truth: np.ndarray) -> tuple[float, float, float]:
    """(mean, mean over the first 20 frames, max) of |est - truth - c|, c the median offset."""
    d = est - truth
    e = np.hypot(*(d - np.median(d, axis=0)).T)
    return float(e.mean()), float(e[:20].mean()), float(e.max())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="mast,side,junction")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--only", default="", help="clips whose name contains one of these")
    ap.add_argument("--cache", default="/tmp/vtrack-suite/cache", help="rendered clips")
    args = ap.parse_args(argv)
    clips = [SynthClip(s, int(k), args.frames) for s in args.scenes.split(",")
             for k in args.seeds.split(",")]
    keys = [k for k in args.only.split(",") if k]
    clips = [c for c in clips if not keys or any(k in c.name for k in keys)]
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    print(f"{'clip':<14}{'sway rms':>10}   {'default: mean / first 20 / max':>32}"
          f"   {'robust: mean / first 20 / max':>32}   (px, full resolution)")
    for clip in clips:
        video = render(clip, cache) / "video.avi"
        truth = true_shift(clip)
        rms = float(np.sqrt(((truth - truth.mean(axis=0)) ** 2).sum(axis=1).mean()))
        cells = [" / ".join(f"{v:6.2f}" for v in errors(estimated_shift(video, r), truth))
                 for r in (False, True)]
        print(f"{clip.name:<14}{rms:10.2f}   {cells[0]:>32}   {cells[1]:>32}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
