"""Memory of a long `vtrack track` run: RSS every N frames while tracking a clip looped R times.

    python scripts/bench_memory.py ../shared/videos/vk_arterial_8lane.mp4 --repeat 25 \
        --every 1000 --count-line 0,216,640,216

The looped clip is written once as MJPG to a temporary folder (about 50 MB per 1000 frames
at 640x360). Prints `frame N rss X MB` lines, then the summary's frame and track counts and each counting
line's tallies.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path


def _rss_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1024
    return float("nan")


def _loop_clip(src: Path, dst: Path, repeat: int) -> int:
    import cv2

    cap = cv2.VideoCapture(str(src))
    frames = []
    while True:
        ok, image = cap.read()
        if not ok:
            break
        frames.append(image)
    fps = cap.get(cv2.CAP_PROP_FPS)
    cap.release()
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(dst), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    for _ in range(repeat):
        for image in frames:
            writer.write(image)
    writer.release()
    return len(frames) * repeat


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("video")
    ap.add_argument("--repeat", type=int, default=25)
    ap.add_argument("--every", type=int, default=1000, help="print RSS every N frames")
    ap.add_argument("--count-line", action="append", default=[],
                    help="X1,Y1,X2,Y2 as for vtrack track --count-line (repeatable)")
    args = ap.parse_args()

    import vtrack.io.video as video
    from vtrack.analytics.regions import parse_cli_line
    from vtrack.app import config
    from vtrack.app.track import TrackOptions, track_video

    plain_iter = video.VideoReader.__iter__

    def sampled(reader):  # the reader's frames, printing RSS every `every` frames
        for frame in plain_iter(reader):
            if frame.index % args.every == 0:
                print(f"frame {frame.index:7d} rss {_rss_mb():6.1f} MB", flush=True)
            yield frame

    video.VideoReader.__iter__ = sampled
    with tempfile.TemporaryDirectory() as tmp:
        clip = Path(tmp) / "looped.avi"
        n = _loop_clip(Path(args.video), clip, args.repeat)
        print(f"{n} frames looped from {args.video}", flush=True)
        cfg = config.load(None)
        cfg.count_lines = [parse_cli_line(line) for line in args.count_line]
        summary = track_video(clip, Path(tmp) / "out", cfg, TrackOptions())
    print(f"end rss {_rss_mb():.1f} MB; {summary['frames']} frames, {summary['tracks']} tracks")
    for i, c in enumerate(summary["counts"]):
        print(f"line {i}: {c['forward']} forward, {c['backward']} backward")


if __name__ == "__main__":
    main()
