"""vtrack track SOURCE: track vehicles in a video file, stream or camera (INTERFACE.md)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from vtrack.analytics.regions import parse_cli_line
from vtrack.errors import InputError
from vtrack.io.sources import LIVE_MODES, parse_source

NAME = "track"
HELP = "track vehicles in a video file, stream (rtsp/http/https) or camera (cam:N)"


def positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"--bin-seconds {text!r}: expected a positive number of seconds")
    return value


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
                   help="counting line in pixels, or with every value in %% of the image "
                        "(0%%,60%%,100%%,60%%); repeatable")
    p.add_argument("--calibration", metavar="CALIB.toml",
                   help="ground-plane calibration (4+ image points with road metres): adds "
                        "speed, length and class to vehicles.csv and classes to counts.csv")
    p.add_argument("--bin-seconds", type=positive_seconds, default=60.0, metavar="S",
                   help="time bin of counts.csv, s (default 60)")
    p.add_argument("--reconnect-seconds", type=float, default=30.0, metavar="S",
                   help="live source: retry a lost connection with back-off for up to S "
                        "seconds, then stop with exit 2 (default 30)")
    p.add_argument("--live", choices=LIVE_MODES, default="auto",
                   help="read the source live (newest frame, frames dropped when tracking "
                        "falls behind, counted) or every frame at the tracker's pace; auto "
                        "(default): live for rtsp://, cameras and http(s) streams of unknown "
                        "length, every frame for files and http(s) videos of known length")
    p.add_argument("--flush-seconds", type=float, default=10.0, metavar="S",
                   help="bring the output files up to date at least every S seconds "
                        "(default 10)")
    p.add_argument("--profile", action="store_true",
                   help="time every stage (decode, image stages, blobs, tracker, outputs) "
                        "and print ms a frame per stage to stderr, also written to "
                        "profile.json; the image stages then run in the main thread, not "
                        "overlapped with tracking (outputs unchanged)")


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
    cfg.count_lines = cfg.count_lines + [parse_cli_line(t) for t in args.count_line]
    calibration = None
    if args.calibration:
        from vtrack.analytics.calibration import load_calibration

        calibration = load_calibration(args.calibration)
    out = Path(args.out) if args.out else Path("runs") / source.stem
    opts = TrackOptions(save_frames=args.save_frames, save_video=args.save_video,
                        rerun=args.rerun, rerun_spawn=args.rerun_spawn,
                        max_frames=args.max_frames, save_detections=args.save_detections,
                        progress=not args.quiet and sys.stdout.isatty(),
                        reconnect_seconds=args.reconnect_seconds,
                        flush_seconds=args.flush_seconds, live=args.live,
                        calibration=calibration, bin_seconds=args.bin_seconds,
                        profile=args.profile)
    summary = track_video(source.spec, out, cfg, opts)
    if args.profile:
        import json

        from vtrack.app import profile

        table = profile.table(json.loads((out / "profile.json").read_text()))
        print(table, file=sys.stderr)
    if not args.quiet:
        counts = ", ".join(f"line {c.get('name', k)}: {c['forward']} fwd / "
                           f"{c['backward']} bwd" for k, c in enumerate(summary["counts"]))
        print(f"{summary['frames']} frames, {summary['tracks']} tracks, "
              f"{summary['fps_processed']} fps -> {out}" + (f"; {counts}" if counts else ""))
        cal = summary.get("calibration")
        if cal:
            px, m = cal["reprojection_px"], cal["reprojection_m"]
            print(f"calibration {cal['file']}: {cal['points']} points, reprojection error "
                  f"mean {px['mean']:.2f} px / {m['mean']:.3f} m, max {px['max']:.2f} px / "
                  f"{m['max']:.3f} m")
    return 0
