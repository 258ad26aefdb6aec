"""The README's picture: one annotated frame of each synthetic scene (overhead, mast, side,
junction), tracked with the default configuration and a counting line at 0.6 H, tiled 2 x 2.

    .venv/bin/python scripts/readme_picture.py [--out docs/img/tracking.jpg] [--frame 160]
        [--frames 200]

Each tile is `vtrack track --save-frames`' own annotated frame (boxes, ids, trails, the
counting line and its tallies), with the scene's name and the frame's ground-truth and track
counts written in the corner.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np

from vtrack.analytics.regions import parse_count_line
from vtrack.app.config import AppConfig
from vtrack.app.track import TrackOptions, track_video
from vtrack.sim.clip import render_default

SCENES = ("overhead", "mast", "side", "junction")
W, H, FPS = 640, 360, 25.0


def _tile(scene: str, frame: int, work: Path, frames: int = 200) -> np.ndarray:
    clip, run = work / scene / "clip", work / scene / "run"
    render_default(clip, scene, frames=frames, width=W, height=H, fps=FPS, seed=0)
    cfg = AppConfig()
    cfg.count_lines = [parse_count_line("line", [0, 0.6 * H, W, 0.6 * H])]
    track_video(clip / "video.avi", run, cfg, TrackOptions(save_frames=True))
    image = cv2.imread(str(run / "frames" / f"{frame:06d}.jpg"))
    gt = np.loadtxt(clip / "gt.csv", delimiter=",", ndmin=2)
    tracks = np.loadtxt(run / "tracks.csv", delimiter=",", ndmin=2)
    text = (f"{scene}, frame {frame}: {int(np.sum(gt[:, 0] == frame))} vehicles in view, "
            f"{int(np.sum(tracks[:, 0] == frame))} tracked")
    cv2.rectangle(image, (0, H - 24), (W, H), (0, 0, 0), -1)
    cv2.putText(image, text, (8, H - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1,
                cv2.LINE_AA)
    return image


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/img/tracking.jpg")
    ap.add_argument("--frame", type=int, default=160)
    ap.add_argument("--frames", type=int, default=200, help="length of each rendered clip")
    args = ap.parse_args()
    if not 1 <= args.frame <= args.frames:
        ap.error("--frame must lie in 1..--frames")
    with tempfile.TemporaryDirectory() as tmp:
        tiles = [_tile(scene, args.frame, Path(tmp), args.frames) for scene in SCENES]
    picture = np.vstack([np.hstack(tiles[:2]), np.hstack(tiles[2:])])
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(args.out, picture, [cv2.IMWRITE_JPEG_QUALITY, 85])
    print(f"wrote {args.out} ({picture.shape[1]}x{picture.shape[0]})")


if __name__ == "__main__":
    main()
