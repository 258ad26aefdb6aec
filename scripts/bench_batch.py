"""Batch throughput: videos per minute with 1 and 2 local workers on the same synthetic
videos, measured in one run (wall time of `run_batch`, pool start-up included).

    .venv/bin/python scripts/bench_batch.py [--videos 6] [--frames 150] [--repeat 1] [--copies]

The videos are rendered by vtrack.sim (different seeds) into a temporary folder; each
measurement tracks all of them into a fresh output folder. On a machine shared with other
work, run it a few times (or with --repeat) and look at the spread.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")


def make_videos(folder: Path, count: int, frames: int, width: int, height: int,
                copies: bool = False) -> None:
    """`count` synthetic videos (seeds 0, 1, ...), or with `copies` one video copied
    `count` times (each worker then does the same work)."""
    import shutil

    from vtrack.sim.traffic import render_scene

    for seed in range(1 if copies else count):
        render_scene(folder / f"clip{seed:02d}", frames=frames, vehicles=12, width=width,
                     height=height, fps=25.0, seed=seed)
    for k in range(1, count if copies else 1):
        (folder / f"clip{k:02d}").mkdir()
        shutil.copy(folder / "clip00" / "video.avi", folder / f"clip{k:02d}" / "video.avi")


def _burn(n: int) -> int:
    s = 0
    for i in range(n):
        s += i
    return s


def free_cores(workers: list[int], n: int = 6_000_000) -> dict[int, float]:
    """Throughput of k pure-CPU processes relative to one (k free cores give ~k): how much
    parallelism the machine offers right now, next to the batch figures."""
    import multiprocessing as mp

    out = {}
    with mp.get_context("spawn").Pool(max(workers)) as pool:
        pool.map(_burn, [10] * max(workers))          # workers started
        base = None
        for k in workers:
            t0 = time.perf_counter()
            pool.map(_burn, [n] * k)
            dt = time.perf_counter() - t0
            base = base or dt
            out[k] = k * base / dt
    return out


def _cpu() -> float:
    """CPU seconds of this process and its finished children (workers, decoders)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def measure(videos: Path, out: Path, workers: int) -> tuple[float, float, int]:
    """(wall seconds, CPU seconds, frames) of one batch over `videos`."""
    from vtrack.batch.runner import run_batch

    c0, t0 = _cpu(), time.perf_counter()
    report = run_batch([str(videos)], out, workers=workers)
    seconds, cpu = time.perf_counter() - t0, _cpu() - c0
    bad = [r for r in report.rows if r["status"] != "ok"]
    if bad:
        sys.exit(f"bench: {len(bad)} videos did not process: {bad[0]['error']}")
    return seconds, cpu, report.frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--videos", type=int, default=6)
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--repeat", type=int, default=1, help="measurements per worker count")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--copies", action="store_true", help="copies of one video instead of "
                    "videos of different seeds")
    args = ap.parse_args()

    from vtrack.batch.runner import cpu_count

    with tempfile.TemporaryDirectory(prefix="vtrack-bench-") as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        make_videos(tmp / "videos", args.videos, args.frames, args.width, args.height,
                    args.copies)
        what = "copies of a synthetic video" if args.copies else "synthetic videos"
        print(f"{args.videos} {what}, {args.frames} frames {args.width}x{args.height}"
              f" each (rendered in {time.perf_counter() - t0:.1f} s); {cpu_count()} cores, "
              f"load average {os.getloadavg()[0]:.1f}")
        results: dict[int, list[tuple[float, float]]] = {w: [] for w in args.workers}
        frames = 0
        for r in range(args.repeat):
            for w in args.workers:   # interleaved, so slow drifts in machine load hit both
                seconds, cpu, frames = measure(tmp / "videos", tmp / f"out-{w}-{r}", w)
                results[w].append((seconds, cpu))
        cores = free_cores(args.workers)
        base = statistics.median(s for s, _ in results[args.workers[0]])
        print(f"\n{'workers':>7}  {'seconds':>8}  {'videos/min':>10}  {'frames/s':>8}  "
              f"{'CPU s':>6}  {'cores busy':>10}  {'ratio':>5}  {'CPU-burner ratio':>16}")
        for w in args.workers:
            s = statistics.median(x for x, _ in results[w])
            c = statistics.median(y for _, y in results[w])
            print(f"{w:>7}  {s:>8.2f}  {60 * args.videos / s:>10.1f}  {frames / s:>8.1f}  "
                  f"{c:>6.1f}  {c / s:>10.2f}  {base / s:>5.2f}  {cores[w]:>16.2f}")
        print(f"\nratio = videos/min with N workers / with {args.workers[0]}; cores busy = CPU "
              f"seconds of the batch (workers and decoder processes) / wall seconds; "
              f"CPU-burner ratio = the same ratio for N pure-Python busy loops, measured "
              f"right after (the parallelism the machine offered); load average now "
              f"{os.getloadavg()[0]:.1f}")
        if args.repeat > 1:
            print(f"median of {args.repeat} runs; all wall seconds:",
                  {w: [round(x, 2) for x, _ in v] for w, v in results.items()})


if __name__ == "__main__":
    main()
