"""Stage timing of a tracking run (`vtrack track --profile`, scripts/bench_pipeline.py).

`instrumented(detector, tracker, times)` wraps each image stage of the detector, the blob
finder, the blob splitter and the tracker's predict and update so that every call adds its
wall time to a named stage of `times`; on leaving it the detector module's functions are
restored. The run's loop times the rest itself (waiting for the decoder, the outputs).
The table lists each stage in ms a frame and the remainder of the wall time that no stage
accounts for; the stages are timed in one thread (the profiled run does not overlap the
image stages with tracking), so they never sum to more than the wall time.
"""

from __future__ import annotations

import contextlib
import inspect
import resource
import time
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator
from typing import Any, NamedTuple

# the order of the table: the order a frame goes through the pipeline
BACKGROUND = "background estimate"
DECODE = "decode/transfer (wait for frame)"
OUTPUTS = "outputs (files, trails, flush)"
COLOURS = "colour signatures (re-identification)"
START = "start-up and close"
DETECTOR_STAGES = (   # (table name, MotionDetector attribute)
    ("prepare (downscale, blur)", "prepare"),
    ("stabilise", "stabiliser"),
    ("gain compensation", "gain"),
    ("MOG2", "background.apply"),
    ("standing hold (labels)", None),
    ("shadows", None),
    ("shift tolerance", "shifted"),
    ("motion map", "motion"),
    ("ghosts (static foreground)", "ghosts"),
    ("morphology", "clean"),
    ("blobs", "tests"),
    ("pieces and large tracked blobs", "_pieces"),
    ("split merged blobs", "_split"),
    ("neck split", "_necks"),
    ("footprint split", "_footprint"),
    ("standing boxes", "standing"),
)
MODULE_STAGES = (   # (table name, function of vtrack.vision.detect called by name)
    ("shadows", "textured_shadow"),
    ("shadows", "drop_shadows"),
    ("blobs", "find_blobs"),
    ("standing hold (labels)", "held_foreground"),
)
TRACKER_STAGES = (("tracker predict", "predict"), ("tracker update", "update"))
APPEARANCE = "appearance model (YOLOX)"   # the fused detector's passes (vision/hybrid.py)
FAR_BAND = "far band (full resolution)"   # the far band's detector, every stage (far.py)
FAR_BAND_CALLS = ("_far_band", "_far_subtract", "_with_far_band")   # MotionDetector's
ORDER = (START, BACKGROUND, DECODE, *(name for name, _ in DETECTOR_STAGES), FAR_BAND,
         APPEARANCE,
         COLOURS, *(name for name, _ in TRACKER_STAGES), OUTPUTS)
# the stages of `vtrack track`'s main thread when it overlaps the image stages (the rest)
MAIN_THREAD = ("blobs", "pieces and large tracked blobs", "split merged blobs", "neck split",
               "footprint split", "standing boxes", COLOURS, "tracker predict",
               "tracker update", OUTPUTS)
# (without --profile the appearance passes run in a thread of their own)
# the image stages `vtrack track` runs in its first worker thread (MotionDetector.align);
# the other image stages run in the second (subtract)
ALIGN_THREAD = ("prepare (downscale, blur)", "stabilise", "gain compensation")
UNACCOUNTED = "not accounted"


class Timing(NamedTuple):
    """Wall and CPU seconds: CPU of this process and of its finished (reaped) children,
    such as the decoder processes of the readers it closed."""

    wall: float
    cpu_self: float
    cpu_children: float

    def __sub__(self, other: Timing) -> Timing:
        return Timing(*(a - b for a, b in zip(self, other, strict=True)))


def now() -> Timing:
    """The wall clock and the CPU used so far by this process and its finished children."""
    own, children = (resource.getrusage(who) for who in (resource.RUSAGE_SELF,
                                                         resource.RUSAGE_CHILDREN))
    return Timing(time.perf_counter(), own.ru_utime + own.ru_stime,
                  children.ru_utime + children.ru_stime)


class StageTimes:
    """Wall seconds per named stage, summed over the run."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self._whole = False   # inside a call of a stage that times its inner stages too

    def wrap(self, name: str, fn: Callable[..., Any], whole: bool = False
             ) -> Callable[..., Any]:
        """`fn` whose calls add their wall time to stage `name`; `whole`: the stages it
        calls count toward `name` alone (the far band's: a detector of its own), not
        toward their own names. Calls in one thread (--profile runs every stage in one)."""
        def timed(*args: Any, **kwargs: Any) -> Any:
            if self._whole:
                return fn(*args, **kwargs)
            t0 = time.perf_counter()
            self._whole = whole
            try:
                return fn(*args, **kwargs)
            finally:
                self._whole = False
                self.seconds[name] += time.perf_counter() - t0
        return timed

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """The block's wall time added to stage `name`."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] += time.perf_counter() - t0

    def iterate(self, name: str, items: Iterable[Any]) -> Iterator[Any]:
        """`items`, with the time spent waiting for each added to stage `name`."""
        it = iter(items)
        while True:
            with self.stage(name):
                item = next(it, _END)
            if item is _END:
                return
            yield item


_END = object()


class _TimedStage:
    """A stage object whose calls are timed; its other attributes read through."""

    def __init__(self, call: Callable[..., Any], stage: Any) -> None:
        self._stage, self._call = stage, call

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self._call(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stage, name)


def _replace(owner: Any, path: str, times: StageTimes, name: str, whole: bool = False
             ) -> None:
    *parents, attr = path.split(".")
    for parent in parents:
        owner = getattr(owner, parent, None)
    stage = getattr(owner, attr, None)
    if stage is not None:
        timed = times.wrap(name, stage, whole)
        setattr(owner, attr, timed if inspect.isroutine(stage) else _TimedStage(timed, stage))


@contextlib.contextmanager
def instrumented(detector: Any, tracker: Any, times: StageTimes) -> Iterator[None]:
    """Inside the block every stage call of `detector` (a MotionDetector, or a fused
    detector: its MotionDetector's and its appearance passes) and `tracker` adds its wall
    time to `times`; stages the detector lacks (switched off) are skipped."""
    from vtrack.vision import detect as detect_module

    if hasattr(detector, "model"):
        _replace(detector.model, "detect", times, APPEARANCE)
        detector = detector.motion
    for name, path in DETECTOR_STAGES:
        if path is not None:
            _replace(detector, path, times, name)
    if getattr(detector, "far_wanted", False):
        for call in FAR_BAND_CALLS:
            _replace(detector, call, times, FAR_BAND, whole=True)
    for name, path in TRACKER_STAGES:
        _replace(tracker, path, times, name)
    saved = {fn: getattr(detect_module, fn) for _, fn in MODULE_STAGES
             if hasattr(detect_module, fn)}
    for name, fn in MODULE_STAGES:
        if fn in saved:
            setattr(detect_module, fn, times.wrap(name, saved[fn]))
    try:
        yield
    finally:
        for fn, original in saved.items():
            setattr(detect_module, fn, original)


def report(times: StageTimes, frames: int, run: Timing) -> dict[str, Any]:
    """The profile of a run of `frames` frames that took `run` (wall and CPU seconds): per
    stage its seconds and ms a frame, and the remainder no stage accounts for (wall - sum)."""
    wall = run.wall
    seconds = dict(times.seconds)
    names = [n for n in ORDER if n in seconds] + sorted(set(seconds) - set(ORDER))
    rows = [(n, seconds[n]) for n in names]
    rows.append((UNACCOUNTED, wall - sum(seconds.values())))
    per = 1000.0 / max(frames, 1)
    return {"frames": frames, "wall_seconds": round(wall, 6),
            "ms_per_frame": round(per * wall, 4),
            "cpu_ms_per_frame": {"process": round(per * run.cpu_self, 4),
                                 "decoder": round(per * run.cpu_children, 4)},
            "stages": [{"stage": n, "seconds": round(s, 6), "ms_per_frame": round(per * s, 4)}
                       for n, s in rows]}


def table(profile: dict[str, Any]) -> str:
    """The profile as a text table: stage, ms a frame, share of the wall time."""
    wall = profile["wall_seconds"] or 1.0
    lines = [f"profile: {profile['frames']} frames, {profile['wall_seconds']:.2f} s wall, "
             f"{profile['ms_per_frame']:.2f} ms a frame; CPU a frame "
             f"{profile['cpu_ms_per_frame']['process']:.2f} ms in this process, "
             f"{profile['cpu_ms_per_frame']['decoder']:.2f} ms in the decoder processes"]
    for row in profile["stages"]:
        lines.append(f"  {row['stage']:<34}{row['ms_per_frame']:8.2f} ms"
                     f"{100 * row['seconds'] / wall:6.1f} %")
    return "\n".join(lines)
