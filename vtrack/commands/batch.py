"""vtrack batch INPUT...: track many videos headlessly, each into its own folder (INTERFACE.md)."""

from __future__ import annotations

import argparse
import sys

from vtrack.errors import InputError

NAME = "batch"
HELP = "track many videos (files, folders, glob patterns), each into its own folder"

EPILOG = """\
Each video gets DIR/<video stem>/ with the files of `vtrack track` (tracks.csv, summary.json,
crossings.csv; frames/, annotated.mp4 and tracks.rrd on request). Videos whose stems collide
get their parent folders' names as a prefix (cam1/0800.mp4 -> cam1_0800). DIR/batch.csv
lists video,out,status,frames,fps_processed,tracks,error (status ok, failed or skipped) and is
rewritten as videos finish. A video whose summary.json says "complete": true is skipped, so
an interrupted batch can simply be run again (--force re-tracks everything). Exit code 0 if
every video is ok or skipped, 2 if any failed, 130 if interrupted.

Engines: local (a process pool), ray or dask (pip install 'vtrack[ray]' / 'vtrack[dask]');
with --address they use an existing cluster whose workers see the same paths, without it
they start a local cluster of --workers workers.
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.epilog = EPILOG
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="video file, folder (scanned recursively) or glob pattern (** recurses)")
    p.add_argument("--out", metavar="DIR", required=True, help="output folder")
    p.add_argument("--config", metavar="CFG.toml", help="TOML config (vtrack config --defaults)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="parallel videos: local pool size, or the size of the local Ray/Dask "
                        "cluster started without --address (default: the number of cores)")
    p.add_argument("--engine", choices=["local", "ray", "dask"], default="local",
                   help="where videos run (default: local)")
    p.add_argument("--address", metavar="ADDR",
                   help="existing Ray/Dask cluster (e.g. 10.0.0.5:6379, tcp://10.0.0.5:8786)")
    p.add_argument("--save-frames", action="store_true", help="write annotated frames/*.jpg")
    p.add_argument("--save-video", action="store_true", help="write annotated.mp4")
    p.add_argument("--rerun", action="store_true", help="write a rerun recording tracks.rrd")
    p.add_argument("--max-frames", type=int, metavar="N", help="stop each video after N frames")
    p.add_argument("--count-line", action="append", default=[], metavar="X1,Y1,X2,Y2",
                   help="counting line in pixels, or every value in %% of the image "
                        "(repeatable)")
    p.add_argument("--force", action="store_true",
                   help="also re-track videos whose output is already complete")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary line")


def run(args: argparse.Namespace) -> int:
    from vtrack.app import config
    from vtrack.batch.runner import run_batch
    from vtrack.analytics.regions import parse_cli_line

    cfg = config.load(args.config)
    cfg.count_lines = cfg.count_lines + [parse_cli_line(t) for t in args.count_line]
    from vtrack.batch.local import resource_tracker_running, stop_resource_tracker

    tracker_was_running = resource_tracker_running()
    try:
        report = run_batch(args.inputs, args.out, cfg, workers=args.workers,
                           engine=args.engine, address=args.address,
                           save_frames=args.save_frames, save_video=args.save_video,
                           rerun=args.rerun, max_frames=args.max_frames,
                           progress=not args.quiet and sys.stdout.isatty(), force=args.force)
    finally:
        # multiprocessing's helper process (local pool, Dask's local workers) started for
        # this batch must not outlive it
        if not tracker_was_running:
            stop_resource_tracker()
    failed = report.failed
    if not args.quiet:
        print(f"{len(report.rows)} videos: {report.count('ok')} ok, "
              f"{report.count('skipped')} skipped, {len(failed)} failed; "
              f"{report.frames} frames in {report.seconds:.1f} s -> {report.csv}")
    if failed:
        first = failed[0]
        raise InputError(f"{len(failed)} of {len(report.rows)} videos failed (see {report.csv}); "
                         f"first: {first['error'] or first['video']}")
    return 0
