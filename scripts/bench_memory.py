"""Memory of a long `vtrack track` run: RSS every N frames while tracking a clip looped R times.

    python scripts/bench_memory.py ../shared/videos/vk_arterial_8lane.mp4 --repeat 25 \
        --every 1000 --count-line 0,216,640,216

The looped clip is written once as MJPG to a temporary folder (about 50 MB per 1000 frames
at 640x360). Prints `frame N rss X MB` lines, then the peak RSS (getrusage), how much the
RSS grew over the second half of the run (flat memory: about 0), the summary's frame and
track counts and each counting line's tallies.
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
    """Write `src` `repeat` times over as one MJPG clip, frame by frame (no frame is kept,
    so the peak RSS is the tracking's); returns its frame count."""
    import cv2

    writer = None
    frames = 0
    for _ in range(repeat):
        cap = cv2.VideoCapture(str(src))
        while True:
            ok, image = cap.read()
            if not ok:
                break
            if writer is None:
                h, w = image.shape[:2]
                writer = cv2.VideoWriter(str(dst), cv2.VideoWriter_fourcc(*"MJPG"),
                                         cap.get(cv2.CAP_PROP_FPS), (w, h))
            writer.write(image)
            frames += 1
        cap.release()
    if writer is not None:
        writer.release()
    return frames


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

    samples: list[tuple[int, float]] = []

    def sampled(reader):  # the reader's frames, printing RSS every `every` frames
        for frame in plain_iter(reader):
            if frame.index % args.every == 0:
                samples.append((frame.index, _rss_mb()))
                print(f"frame {frame.index:7d} rss {samples[-1][1]:6.1f} MB", flush=True)
            yield frame

    video.VideoReader.__iter__ = sampled
    with tempfile.TemporaryDirectory() as tmp:
        clip = Path(tmp) / "looped.avi"
        n = _loop_clip(Path(args.video), clip, args.repeat)
        print(f"{n} frames looped from {args.video}", flush=True)
        cfg = config.load(None)
        cfg.count_lines = [parse_cli_line(line) for line in args.count_line]
        summary = track_video(clip, Path(tmp) / "out", cfg, TrackOptions())
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024   # KiB on Linux
    half = [rss for index, rss in samples if index > n / 2]
    growth = half[-1] - half[0] if half else float("nan")
    print(f"peak rss {peak:.1f} MB; rss growth over the second half {growth:+.1f} MB "
          f"({len(half)} samples)")
    print(f"end rss {_rss_mb():.1f} MB; {summary['frames']} frames, {summary['tracks']} tracks")
    for i, c in enumerate(summary["counts"]):
        print(f"line {i}: {c['forward']} forward, {c['backward']} backward")


if __name__ == "__main__":
    main()
