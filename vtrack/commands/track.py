"""vtrack track SOURCE: track vehicles in a video file, stream or camera (INTERFACE.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from vtrack.errors import InputError
from vtrack.vision.sources import parse_source

NAME = "track"
HELP = "track vehicles in a video file, stream (rtsp/http/https) or camera (cam:N)"


def parse_count_line(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"--count-line {text!r}: expected X1,Y1,X2,Y2 (numbers)") from None
    from vtrack.app.config import parse_line

    return parse_line(f"--count-line {text!r}", values)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("video", metavar="SOURCE",
                   help="video file (any container/codec OpenCV reads), rtsp://, http:// or "
                        "https:// address (used exactly as given), or cam:N (camera N)")
    p.add_argument("--out", metavar="DIR", help="output folder (default runs/<source stem>/)")
    p.add_argument("--config", metavar="CFG.toml", help="TOML config (vtrack config --defaults)")
    p.add_argument("--save-frames", action="store_true", help="write annotated frames/*.jpg")
    p.add_argument("--save-video", action="store_true", help="write annotated.mp4")
    p.add_argument("--rerun", metavar="FILE.rrd", help="write a rerun recording")
    p.add_argument("--rerun-spawn", action="store_true",
                   help="also stream to a live rerun viewer (desktop)")
    p.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary line")
    p.add_argument("--save-detections", action="store_true",
                   help="also write detections.csv: the detector's boxes per frame "
                        "(MOTChallenge detection rows frame,-1,x,y,w,h,1,-1,-1,-1)")
    p.add_argument("--count-line", action="append", default=[], metavar="X1,Y1,X2,Y2",
                   help="counting line in pixels (repeatable)")
    p.add_argument("--reconnect-seconds", type=float, default=30.0, metavar="S",
                   help="live source: retry a lost connection with back-off for up to S "
                        "seconds, then stop with exit 2 (default 30)")
    p.add_argument("--flush-seconds", type=float, default=10.0, metavar="S",
                   help="bring the output files up to date at least every S seconds "
                        "(default 10)")


def run(args: argparse.Namespace) -> int:
    from vtrack.app import config
    from vtrack.app.track import TrackOptions, track_video

    if args.max_frames is not None and args.max_frames < 1:
        raise InputError("--max-frames must be a positive integer")
    if not 0 <= args.reconnect_seconds < float("inf"):
        raise InputError("--reconnect-seconds must be a number >= 0")
    if not 0 < args.flush_seconds < float("inf"):
        raise InputError("--flush-seconds must be a positive number")
    source = parse_source(args.video)
    cfg = config.load(args.config)
    cfg.count_lines = cfg.count_lines + [parse_count_line(t) for t in args.count_line]
    out = Path(args.out) if args.out else Path("runs") / source.stem
    opts = TrackOptions(save_frames=args.save_frames, save_video=args.save_video,
                        rerun=args.rerun, rerun_spawn=args.rerun_spawn,
                        max_frames=args.max_frames, save_detections=args.save_detections,
                        progress=not args.quiet and sys.stdout.isatty(),
                        reconnect_seconds=args.reconnect_seconds,
                        flush_seconds=args.flush_seconds)
    summary = track_video(source.spec, out, cfg, opts)
    if not args.quiet:
        counts = ", ".join(f"line {k}: {c['forward']} fwd / {c['backward']} bwd"
                           for k, c in enumerate(summary["counts"]))
        print(f"{summary['frames']} frames, {summary['tracks']} tracks, "
              f"{summary['fps_processed']} fps -> {out}" + (f"; {counts}" if counts else ""))
    return 0
