"""`vtrack track`: video file, stream or camera -> MOG2 detections -> tracker -> tracks.csv,
crossings.csv, summary.json, annotated frames/video and an optional rerun recording.

The output files are kept by sinks (`outputs`): flushed after the first frame, at least
every `flush_seconds` and at the end, each time with summary.json last, so the folder holds
valid files at any moment and a crash loses at most the last interval. On an interruption,
a decoder failure or a live source that is lost, what was processed is flushed with
"complete": false. Memory stays flat however long a live source runs.
"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vtrack import __version__
from vtrack.app.config import AppConfig
from vtrack.analytics.calibration import Calibration
from vtrack.analytics.traffic import TrafficAnalytics
from vtrack.app.outputs import (DetectionsCsv, FrameTimes, Sink, TrackedFrame, TrackEnds,
                                TracksCsv, TrafficSink)
from vtrack.app import profile
from vtrack.app.readonce import fits, read_once, sample_numbers
from vtrack.errors import InputError
from vtrack.fileio import replace_dir, write_json
from vtrack.tracking.tracker import FrameTracks, Tracker
from vtrack.vision.appearance import VEHICLE_CLASSES
from vtrack.vision.colour import signatures
from vtrack.io.sources import parse_source


APPEARANCE_AHEAD = 8   # frames read before they go on to be tracked: the passes' slack


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


@dataclass
class TrackOptions:
    save_frames: bool = False
    save_video: bool = False
    rerun: str | None = None          # path of the .rrd to write
    rerun_spawn: bool = False         # also stream to a live viewer
    max_frames: int | None = None
    progress: bool = False
    save_detections: bool = False     # also write detections.csv (the detector's boxes)
    calibration: Calibration | None = None   # ground plane: speeds, lengths, classes
    bin_seconds: float = 60.0                 # time bin of counts.csv
    reconnect_seconds: float = 30.0   # a live source silent this long is lost (exit 2)
    flush_seconds: float = 10.0       # outputs brought up to date at least this often
    live: str = "auto"                # --live auto|yes|no (io.sources.live_request)
    profile: bool = False             # time every stage into profile.json (app/profile.py)
    cv_threads: int = 1               # OpenCV's threads during the run (0: its default)
    warn: Callable[[str], None] = _warn


class Trails:
    """The recent path (box centres) of each live track, for drawing."""

    def __init__(self, length: int) -> None:
        self.length = length
        self.paths: dict[int, list[tuple[float, float]]] = {}

    def update(self, f: TrackedFrame) -> None:
        for _, tid, x, y, w, h, _ in f.tracks.rows.tolist():
            path = self.paths.setdefault(int(tid), [])
            path.append((x + w / 2.0, y + h / 2.0))
            del path[: -self.length]
        for tid in f.ended:
            self.paths.pop(tid, None)


class TrackJob:
    """One video file, stream or camera tracked into one output folder."""

    def __init__(self, video: str | Path, out_dir: str | Path, cfg: AppConfig,
                 opts: TrackOptions) -> None:
        self.source = parse_source(video)
        self.out = Path(out_dir)
        self.cfg = cfg
        self.opts = opts
        if opts.calibration is None and cfg.calibration:   # --calibration overrides it
            from vtrack.analytics.calibration import load_calibration

            self.opts = dataclasses.replace(opts, calibration=load_calibration(cfg.calibration))
        self.trails = Trails(cfg.output.trail_length)
        self.info: Any = None
        self.reader: Any = None
        self.sinks: list[Sink] = []
        self.analytics: TrafficAnalytics | None = None
        self.detections: DetectionsCsv | None = None
        self.frames = 0
        self.elapsed = 0.0
        self.stopped_by: str | None = None   # why the run ended (None while it runs)
        self.error: str | None = None
        self.times = profile.StageTimes() if opts.profile else None   # --profile
        self._wanted: set[int] = set()   # frames sampled for the background estimate
        self._ahead = False              # ... taken from this read (readonce.read_once)

    # ------------------------------------------------------------------ running
    def run(self) -> dict[str, Any]:
        """Track the whole source; returns the summary (also on interruption or a lost
        source, then re-raised)."""
        start = profile.now()
        with opencv_threads(self.opts.cv_threads):
            return self._run(start)

    def _run(self, start: profile.Timing) -> dict[str, Any]:
        from vtrack.vision.hybrid import make_detector
        from vtrack.io.video import VideoReader

        self.reader = VideoReader(self.source, max_frames=self.opts.max_frames,
                                  reconnect_seconds=self.opts.reconnect_seconds,
                                  live=self.opts.live)
        self.info = self.reader.info
        try:   # a calibration for another frame size fails here, before any output
            self.analytics = TrafficAnalytics(
                self.out, self.info.width, self.info.height, self.info.fps,
                self.cfg.count_lines, self.cfg.zones, self.opts.calibration,
                self.opts.bin_seconds, gates=self.cfg.gates,
                looks_classes=VEHICLE_CLASSES if self.cfg.detector.kind != "mog2" else ())
        except BaseException:
            self.reader.close()
            raise
        if self.opts.calibration is not None and (warning := self.opts.calibration.warning()):
            self.opts.warn(warning)
        self._prepare_out_dir()
        parts: list[Any] = []   # progress bar, video writer, rerun logger: closed at the end
        detector: Any = None    # its appearance worker (if any) stops at the end
        try:
            roi = self.cfg.roi.pixels(self.info.width, self.info.height) if self.cfg.roi \
                else None
            detector = make_detector(self.cfg.detector, self.info.width, self.info.height,
                                     self.info.fps, roi, threaded=self.times is None)
            self._wanted = self._background_sample_numbers(detector)
            self._ahead = bool(self._wanted) and self._read_once(detector)
            if self._wanted and not self._ahead:
                # a second read of the start, for a run that needs the full frames later
                # or would keep too many frames while reading ahead (app/readonce.py)
                with self._stage(profile.BACKGROUND, outside_loop=True):
                    detector.initialise(self._background_samples())
            tracker = Tracker(self.cfg.tracker, self.info.width, self.info.height,
                              self.info.fps)
            self.sinks = self._sinks(tracker)
            for open_part in (self._progress, self._open_writer, self._open_rerun):
                parts.append(open_part())
            self._loop(detector, tracker, *parts)
            self.stopped_by = ("max-frames" if self.opts.max_frames
                               and self.frames >= self.opts.max_frames else "end")
        except KeyboardInterrupt:
            self.stopped_by = "interrupted"
            raise
        except InputError as exc:   # the source failed (or was lost) after the first frame
            self.stopped_by, self.error = "error", str(exc)
        finally:
            summary = self._finish(parts + [detector])
            if self.times is not None:
                write_json(self.out / "profile.json", self._profile(start))
        if self.error:
            raise InputError(self.error)
        return summary

    def _loop(self, detector: Any, tracker: Tracker, bar: Any, writer: Any,
              logger: Any) -> None:
        times = FrameTimes(tracker.max_row_lag + 1)
        ends = TrackEnds()
        next_flush = 0.0   # the first frame is flushed at once
        t0 = time.perf_counter()
        with self._frames(detector, tracker) as frames:
            for frame, fg in frames:
                # The tracker predicts on every frame (the detector's warm-up included) once
                # the camera's motion is known; the detector divides a blob holding several
                # predicted vehicles among them.
                predicted = tracker.predict(frame.time, fg.motion)
                dets = detector.locate(fg, predicted)
                with self._stage(profile.COLOURS):
                    colours = signatures(frame.image, dets.boxes)
                ft = tracker.update(frame.index, frame.time, dets.centers, dets.boxes,
                                    dets.changed, dets.seen, colours)
                self.frames = frame.index
                with self._stage(profile.OUTPUTS):
                    if self.detections is not None:
                        self.detections.add(frame.index, dets.boxes, dets.score)
                    times.add(frame.index, frame.time)
                    tf = TrackedFrame(frame.index, frame.time, ft, ends.update(ft), times,
                                      *looks(ft, dets))
                    for sink in self.sinks:
                        sink.frame(tf)
                    self.trails.update(tf)
                    if self.opts.save_frames or writer is not None:
                        self._annotate(frame, ft, dets, writer)
                    if logger is not None:
                        logger.log_frame(frame, dets, ft, fg.mask)
                        logger.log_trails(self.trails.paths)
                    self.elapsed = time.perf_counter() - t0
                    if bar is not None:
                        bar.update(1)
                    if time.monotonic() >= next_flush:
                        self._flush()
                        next_flush = time.monotonic() + self.opts.flush_seconds
        if self.times is not None:   # the loop's wall time less the stages is unaccounted
            self.times.seconds[profile.START] -= time.perf_counter() - t0

    @contextlib.contextmanager
    def _frames(self, detector: Any, tracker: Tracker) -> Iterator[Iterator[tuple[Any, Any]]]:
        """(frame, foreground) pairs: `segmented` (the image stages of the next frame in a
        worker thread), or with --profile every stage timed, all in this thread."""
        source: Iterable[Any] = self.reader
        if self.times is not None:
            source = self.times.iterate(profile.DECODE, source)
        with contextlib.ExitStack() as stack:
            if self.times is not None:
                stack.enter_context(profile.instrumented(detector, tracker, self.times))
            if self._ahead:
                frames = read_once(source, detector, self._wanted,
                                   lambda: self._stage(profile.BACKGROUND))
            else:
                frames = ((frame, False) for frame in source)
            if hasattr(detector, "request"):   # the appearance model sees each frame read
                frames = requested(frames, detector, 0 if self.times else APPEARANCE_AHEAD)
            if self.times is None:
                # closing: the worker stops with the loop, also when the loop body raises
                yield stack.enter_context(contextlib.closing(segmented(frames, detector)))
            else:
                yield ((frame, detector.segment(frame.image, prepared))
                       for frame, prepared in frames)

    @contextlib.contextmanager
    def _stage(self, name: str, outside_loop: bool = False) -> Iterator[None]:
        """With --profile, the block's wall time added to stage `name` (`outside_loop`:
        and not to the start-up, the run's wall time outside the frame loop)."""
        if self.times is None:
            yield
            return
        t0 = time.perf_counter()
        with self.times.stage(name):
            yield
        if outside_loop:
            self.times.seconds[profile.START] -= time.perf_counter() - t0

    def _profile(self, start: profile.Timing) -> dict[str, Any]:
        """The stage table of the run that began at `start` (its decoders are closed);
        "start-up and close" is the wall time outside the frame loop and the stages timed
        before it (a second read's background estimate)."""
        assert self.times is not None
        run = profile.now() - start
        self.times.seconds[profile.START] += run.wall
        return profile.report(self.times, self.frames, run)

    def _finish(self, parts: list[Any]) -> dict[str, Any]:
        """Stop the decoder, close the video and recording, keep the decoder's log, flush
        every output a last time; returns the summary."""
        self.reader.close()
        for part in parts:
            if part is not None:
                part.close()
        log = self.out / "decoder.log"
        if self.reader.save_decoder_log(log) and self.error:
            self.error += f" (decoder messages in {log})"
        summary = self._flush(final=True)
        for sink in self.sinks:
            sink.close()
        return summary

    def _sinks(self, tracker: Tracker) -> list[Sink]:
        """The per-frame consumers that own output files (add new outputs here)."""
        sinks: list[Sink] = [TracksCsv(self.out / "tracks.csv", tracker.max_row_lag),
                             TrafficSink(self.analytics)]
        if self.opts.save_detections:
            self.detections = DetectionsCsv(self.out / "detections.csv")
            sinks.append(self.detections)
        return sinks

    def _background_sample_numbers(self, detector: Any) -> set[int]:
        """The numbers of the frames the detector's background is estimated from
        (readonce.sample_numbers): none for a live source (a live stream read every frame
        (--live no) has no known start either), else those of a file or a stream of known
        length (a file on a web server)."""
        if self.reader.live or not (self.source.is_file or self.info.frame_count):
            return set()
        cfg = self.cfg.detector
        return sample_numbers(self.info.fps, self.info.frame_count, self.opts.max_frames,
                              cfg.init_background_seconds, cfg.init_background_samples)

    def _read_once(self, detector: Any) -> bool:
        """Whether the background's samples come from the tracking's own read
        (readonce.read_once): when no output needs the full frames the detector's look-ahead
        drops, and that look-ahead fits in memory."""
        full_frames = self.opts.save_frames or self.opts.save_video or self.opts.rerun \
            or self.opts.rerun_spawn or hasattr(detector, "request")
        return not full_frames and fits(self._wanted, detector.prepare.size)

    def _background_samples(self) -> Iterator[Any]:
        """The frames numbered in `self._wanted` from a second, supervised read of the
        source's start that hands over only those frames. A file that fails here gives what
        was read: the main read reports the failure."""
        from vtrack.io.video import VideoReader

        with VideoReader(self.source, keep=self._wanted, live="no",
                         reconnect_seconds=self.opts.reconnect_seconds) as reader:
            try:
                for frame in reader:
                    yield frame.image
            except InputError:
                return

    def _prepare_out_dir(self) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        # Re-running into a folder replaces it: no stale frames, video or log from an
        # earlier run (tracks.csv, crossings.csv and summary.json are replaced at the
        # first flush).
        for stale in ("annotated.mp4", "decoder.log", "detections.csv", "vehicles.csv",
                      "counts.csv", "zone_events.csv", "crossings.csv", "movements.csv",
                      "speeds.csv", "profile.json"):
            (self.out / stale).unlink(missing_ok=True)
        if (self.out / "frames").exists() or self.opts.save_frames:
            replace_dir(self.out / "frames")
            if not self.opts.save_frames:
                (self.out / "frames").rmdir()

    def _open_writer(self) -> Any:
        if not self.opts.save_video:
            return None
        from vtrack.io.video_writer import open_video_writer

        writer = open_video_writer(self.out / "annotated.mp4", self.info.fps,
                                   (self.info.width, self.info.height))
        if writer.warning:
            self.opts.warn(writer.warning)
        return writer

    def _open_rerun(self) -> Any:
        if not (self.opts.rerun or self.opts.rerun_spawn):
            return None
        from vtrack.viz.rerun_log import TrackLogger  # imports rerun only when asked

        return TrackLogger(self.opts.rerun, self.info, self.cfg, spawn=self.opts.rerun_spawn)

    def _progress(self) -> Any:
        if not self.opts.progress:
            return None
        from tqdm import tqdm

        total = self.info.frame_count or None
        if self.opts.max_frames:
            total = min(total or self.opts.max_frames, self.opts.max_frames)
        desc = Path(self.source.spec).name if self.source.is_file else self.source.spec
        return tqdm(total=total, unit="frame", desc=desc, file=sys.stderr,
                    dynamic_ncols=True)

    def _annotate(self, frame: Any, ft: FrameTracks, dets: Any, writer: Any) -> None:
        from vtrack.vision.annotate import draw_frame, save_jpeg

        counts = self.analytics.line_counts()
        img = draw_frame(frame.image, ids=ft.ids, boxes=ft.boxes, coasted=ft.coasted,
                         trails={i: self.trails.paths.get(int(i), []) for i in ft.ids},
                         detections=dets, lines=self.analytics.lines_px, counts=counts,
                         frame_index=frame.index, regions=self.analytics.regions_px)
        if self.opts.save_frames:
            save_jpeg(self.out / "frames" / f"{frame.index:06d}.jpg", img,
                      quality=self.cfg.output.jpeg_quality)
        if writer is not None:
            writer.write(img, frame.time)

    # ------------------------------------------------------------------ writing
    def _flush(self, final: bool = False) -> dict[str, Any]:
        """Bring every output file up to date, summary.json last (`final`: the run is over);
        returns the summary."""
        entries: dict[str, Any] = {"tracks": 0, "counts": []}  # before the first frame
        for sink in self.sinks:
            entries.update(sink.flush(final))
        summary = {
            "video": self.source.spec,
            "frames": self.frames,
            "width": self.info.width,
            "height": self.info.height,
            "fps_video": float(self.info.fps),
            "fps_processed": round(self.frames / self.elapsed, 2) if self.elapsed > 0 else 0.0,
            **entries,
            "complete": self.stopped_by in ("end", "max-frames"),
            "stopped_by": self.stopped_by,
            "live": self.reader.live,
            "reconnects": self.reader.reconnects,
            "dropped_frames": self.reader.dropped_frames,
            "vtrack_version": __version__,
            "config_hash": self.cfg.digest(),
            "config": self.cfg.to_dict(),
        }
        if self.error:
            summary["error"] = self.error
        write_json(self.out / "summary.json", summary)
        return summary


@contextlib.contextmanager
def opencv_threads(n: int) -> Iterator[None]:
    """OpenCV's thread pool at `n` threads inside the block (0: unchanged). The pipeline
    keeps the cores busy with its own threads (the decoder process, the image stages'
    worker, the tracking); OpenCV's pool on top of them costs ~1 ms of CPU a frame at
    1280x720 for no gain in wall time (docs/RESULTS.md, Speed)."""
    if n <= 0:
        yield
        return
    import cv2

    before = cv2.getNumThreads()
    cv2.setNumThreads(n)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def segmented(frames: Iterable[tuple[Any, bool]], detector: Any
              ) -> Iterator[tuple[Any, Any]]:
    """(frame, detector.segment(frame.image, prepared)) for each (frame, prepared) of
    `frames`, in order. The image stages run in two worker threads, a three-stage pipeline:
    while the caller handles frame n, one thread runs `detector.subtract` (MOG2 and what
    follows it) of frame n + 1 and the other `detector.align` (prepare, stabilise, gain) of
    frame n + 2 (they need no track state, their halves keep separate state, and OpenCV
    releases the GIL): two frames of latency, the same results. `subtract` of frame n + 1
    starts only once the caller has asked for frame n, so it holds the standing boxes
    located up to frame n - 1 (detect.HOLD_LAG) whatever the threads' timing. A source that
    fails after some frames (InputError) still gives the frames in hand before the error
    is raised."""
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="vtrack-align") as first, \
            ThreadPoolExecutor(max_workers=1, thread_name_prefix="vtrack-subtract") as second:
        aligning: tuple[Any, Future] | None = None      # aligned, not yet subtracted
        subtracting: deque[tuple[Any, Future]] = deque()
        failure: InputError | None = None

        def subtract(aligned: Future) -> Any:
            return detector.subtract(aligned.result())

        try:
            for frame, prepared in frames:
                ahead = (frame, first.submit(detector.align, frame.image, prepared))
                if aligning is not None:
                    subtracting.append((aligning[0], second.submit(subtract, aligning[1])))
                aligning = ahead
                while len(subtracting) > 1:
                    done, foreground = subtracting.popleft()
                    yield done, foreground.result()
        except InputError as exc:
            failure = exc
        if aligning is not None:
            subtracting.append((aligning[0], second.submit(subtract, aligning[1])))
        while subtracting:
            done, foreground = subtracting.popleft()
            yield done, foreground.result()
        if failure is not None:
            raise failure


def looks(ft: FrameTracks, dets: Any) -> tuple[Any, Any]:
    """Per confirmed track, the appearance class and score of the detection that updated it
    this frame (-1 and 0 where none, or a motion-only blob)."""
    det = ft.detection_of
    used = det >= 0
    cls = np.full(len(det), -1)
    score = np.zeros(len(det))
    cls[used], score[used] = dets.cls[det[used]], dets.score[det[used]]
    score[cls < 0] = 0.0
    return cls, score


def requested(frames: Iterable[tuple[Any, bool]], detector: Any, ahead: int = 0
              ) -> Iterator[tuple[Any, bool]]:
    """`frames`, each handed to `detector.request` (its appearance pass starts in the
    detector's worker) as it is read, in this thread, and passed on `ahead` frames later:
    a pass has the time of `ahead` more frames to finish before its frame is located, so
    the tracking waits less for it (the passes' frames depend on the frame numbers alone:
    the results do not change). A source that fails (InputError) still gives the frames
    read before the error is raised."""
    held: deque[tuple[Any, bool]] = deque()
    failure: InputError | None = None
    try:
        for frame, prepared in frames:
            detector.request(frame.image)
            held.append((frame, prepared))
            if len(held) > ahead:
                yield held.popleft()
    except InputError as exc:
        failure = exc
    while held:
        yield held.popleft()
    if failure is not None:
        raise failure


def track_video(video: str | Path, out_dir: str | Path, cfg: AppConfig,
                opts: TrackOptions | None = None) -> dict[str, Any]:
    """Track one video file, stream or camera into `out_dir`; returns summary.json's
    content."""
    return TrackJob(video, out_dir, cfg, opts or TrackOptions()).run()
