"""Tracked fps divided by decode-only fps on a 1280x720 MJPG video from `vtrack synth`,
measured in one run, and what each stage of the detector and the tracker costs per frame.
Start-up (process spawn, model set-up) is excluded by subtracting a one-frame run from each
timing; the tracked run includes the second read of the video's first seconds that
estimates the background.

It also prints the CPU time each run spends per frame, in this process and in the decoder
children, and what that work allows: a run that needs C ms of CPU a frame on N cores takes
at least C / N ms a frame, so the ratio cannot exceed N x (decode-only ms a frame) / C,
however the work is spread over threads and processes.

    .venv/bin/python scripts/bench_pipeline.py [--frames 300] [--scene mast] [--config CFG]
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from vtrack.app import config
from vtrack.app.track import TrackJob, TrackOptions, track_video
from vtrack.tracking.tracker import Tracker
from vtrack.vision import detect as detect_module
from vtrack.vision.detect import MotionDetector
from vtrack.io.video import VideoReader


# The stages `vtrack track` runs in its main thread; the rest run in the segment worker.
MAIN_THREAD = ("blobs", "split merged blobs", "standing boxes", "tracker predict",
               "tracker update")
BACKGROUND = "background estimate (2nd read)"  # before the first frame
TARGET_RATIO = 0.45  # issue 12's target for the ratio tracked / decode-only fps


class Timing(NamedTuple):
    """Wall and CPU seconds of a run: CPU in this process and in its finished children."""

    wall: float
    cpu_self: float
    cpu_children: float

    def __sub__(self, other: Timing) -> Timing:
        return Timing(*(a - b for a, b in zip(self, other, strict=True)))


def _now() -> Timing:
    """The wall clock and the CPU used so far by this process and its finished children."""
    own, children = (resource.getrusage(who) for who in (resource.RUSAGE_SELF,
                                                         resource.RUSAGE_CHILDREN))
    return Timing(time.perf_counter(), own.ru_utime + own.ru_stime,
                  children.ru_utime + children.ru_stime)


def _timed(run: Callable[[], Any]) -> Timing:
    """Time run(); the children are the decoder processes it started and closed."""
    before = _now()
    run()
    return _now() - before


def _decode(video: Path, frames: int) -> Timing:
    def read() -> None:
        with VideoReader(video, max_frames=frames) as reader:
            for _ in reader:
                pass
    return _timed(read)


def _track(video: Path, out: Path, cfg: config.AppConfig, frames: int) -> Timing:
    return _timed(lambda: track_video(video, out, cfg, TrackOptions(max_frames=frames)))


class StageTimes:
    """Wall time per named stage, summed over the frames."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds[name] += time.perf_counter() - t0
        return timed


class _TimedStage:
    """A detector stage object whose calls are timed; its attributes read through."""

    def __init__(self, times: StageTimes, name: str, stage: Any) -> None:
        self._stage, self._call = stage, times.wrap(name, stage)

    def __call__(self, *args: Any) -> Any:
        return self._call(*args)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stage, name)


def stage_costs(video: Path, cfg: config.AppConfig, frames: int) -> tuple[StageTimes, int]:
    """Run detector and tracker in process with every stage timed."""
    times = StageTimes()
    job = TrackJob(video, "/nonexistent", cfg, TrackOptions(max_frames=frames))
    reader = VideoReader(video, max_frames=frames)
    job.info = info = reader.info
    det = MotionDetector(cfg.detector, info.width, info.height, info.fps)
    t0 = time.perf_counter()
    det.initialise(job._background_samples())
    times.seconds[BACKGROUND] += time.perf_counter() - t0
    det.prepare = times.wrap("prepare (downscale, blur)", det.prepare)
    if det.stabiliser is not None:
        det.stabiliser = _TimedStage(times, "stabilise", det.stabiliser)
    if det.gain is not None:
        det.gain = times.wrap("gain compensation", det.gain)
    det.background.apply = times.wrap("MOG2", det.background.apply)
    det.clean = times.wrap("morphology", det.clean)
    if det.shifted is not None:
        det.shifted = times.wrap("shift tolerance", det.shifted)
    if det.motion is not None:
        det.motion = times.wrap("motion map", det.motion)
    for name, stage in (("shadows", "textured_shadow"), ("blobs", "find_blobs"),
                        ("standing hold (labels)", "held_foreground")):
        setattr(detect_module, stage, times.wrap(name, getattr(detect_module, stage)))
    det._split = times.wrap("split merged blobs", det._split)
    if det.standing is not None:
        det.standing = times.wrap("standing boxes", det.standing)
    tracker = Tracker(cfg.tracker, info.width, info.height, info.fps)
    predict = times.wrap("tracker predict", tracker.predict)
    update = times.wrap("tracker update", tracker.update)
    n = 0
    with reader:
        for frame in reader:
            fg = det.segment(frame.image)
            dets = det.locate(fg, predict(frame.time, fg.motion))
            update(frame.index, frame.time, dets.centers, dets.boxes, dets.changed)
            n += 1
    return times, n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--scene", default="mast", help="synthetic scene (default mast: a "
                    "swaying camera, shadows, perspective)")
    ap.add_argument("--config", help="TOML config for the tracked run (default config if absent)")
    args = ap.parse_args()
    cfg = config.load(args.config)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.scene == "overhead":
            from vtrack.sim.traffic import render_scene

            render_scene(tmp / "synth", frames=args.frames, vehicles=20, width=1280,
                         height=720, fps=25.0, seed=0)
        else:
            from vtrack.sim.clip import render_preset
            from vtrack.sim.nuisance import parse_nuisances

            render_preset(tmp / "synth", args.scene, frames=args.frames, width=1280,
                          height=720, fps=25.0, seed=0, nuisances=parse_nuisances("all"))
        video = tmp / "synth" / "video.avi"
        n = args.frames - 1
        decode = _decode(video, args.frames) - _decode(video, 1)
        track = _track(video, tmp / "out", cfg, args.frames) - _track(video, tmp / "o1", cfg, 1)
        stages, frames = stage_costs(video, cfg, args.frames)
    cores = len(os.sched_getaffinity(0))
    print(f"video: 1280x720 MJPG (vtrack synth --scene {args.scene}), {args.frames} frames; "
          f"detect_width {cfg.detector.detect_width}")
    print(f"decode only : {n / decode.wall:8.1f} fps")
    print(f"tracked     : {n / track.wall:8.1f} fps")
    print(f"ratio tracked/decode: {decode.wall / track.wall:.3f}")
    print("CPU per frame (ms): this process / decoder children / wall")
    for name, t in (("decode only", decode), ("tracked", track)):
        print(f"  {name:<12}{1000 * t.cpu_self / n:7.2f} {1000 * t.cpu_children / n:7.2f}"
              f" {1000 * t.wall / n:7.2f}")
    cpu = track.cpu_self + track.cpu_children
    print(f"the tracked run's CPU work on {cores} cores allows a ratio of at most "
          f"{cores * decode.wall / cpu:.3f} ({TARGET_RATIO} needs at most "
          f"{1000 * cores * decode.wall / TARGET_RATIO / n:.2f} ms of CPU a frame, this run "
          f"took {1000 * cpu / n:.2f})")
    print(f"per frame (in-process, {frames} frames):")
    for name, sec in sorted(stages.seconds.items(), key=lambda kv: -kv[1]):
        print(f"  {name:<34}{1000 * sec / frames:7.2f} ms")
    # `vtrack track` runs the image stages of frame n + 1 in a worker thread while frame n
    # is tracked (app/track.py: segmented): the larger of the two sums bounds the rate.
    worker = sum(sec for name, sec in stages.seconds.items()
                 if name not in MAIN_THREAD and name != BACKGROUND)
    main = sum(stages.seconds.get(name, 0.0) for name in MAIN_THREAD)
    print(f"  image stages (worker thread){1000 * worker / frames:13.2f} ms; "
          f"blobs, split and tracker (main thread){1000 * main / frames:7.2f} ms")


if __name__ == "__main__":
    main()
