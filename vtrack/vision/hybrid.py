"""The fused detector (`[detector] kind = "hybrid"` or `"appearance"`): the MOG2 detector
(detect.py) and the appearance detector (appearance.py) side by side, their boxes fused
(fusion.py).

The appearance model runs in a worker thread of its own, beside the image stages and the
tracking, on the frames the schedule picks: the whole frame every `appearance_seconds` of
video (every frame for `appearance`, and for a video slower than 1 / appearance_seconds).
It is asked for frame n when the frame is read (`request`), before the tracker reaches it,
and its boxes are taken when the frame's blobs are located (`locate`): reading never waits
for it, and the results do not depend on the threads' timing (the schedule depends on the
frame's number alone). With `appearance_tiles` a pass half-way between two of them looks
at one tile of the frame in turn, for the far vehicles (appearance.tiles, fusion.renew).

Between two passes the appearance boxes ride on the blobs they explained, and those of
standing vehicles (no blob) are held where nothing moves (fusion.follow): every frame is
measured with the same whole boxes, and a queued vehicle keeps its measurement however
long it stands.
"""

from __future__ import annotations

import os
import sys
import threading
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from vtrack.boxes import centre
from vtrack.vision.appearance import AppearanceModel, Window, tiles
from vtrack.vision.detect import Detections, DetectorConfig, Foreground, MotionDetector
from vtrack.vision.fusion import Fused, follow, renew

WORKER_NICENESS = 10   # the appearance worker's scheduling niceness above the process's


def yield_to_the_pipeline() -> None:
    """Lower the calling thread's scheduling priority by WORKER_NICENESS (Linux keeps a
    nice value per thread): the appearance passes, read ahead (app/track.py), take the
    cores' idle time before the tracking's and the image stages', which every frame waits
    for. Elsewhere than on Linux (where a thread id is no process id) nothing changes."""
    if not sys.platform.startswith("linux"):
        return
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid)
                       + WORKER_NICENESS)
    except (AttributeError, OSError):
        pass


class FusedDetector:
    """MOG2 blobs and appearance boxes fused, behind the interface of MotionDetector (the
    image stages are its own; `request` must be called with each frame's full image, in
    order, before that frame is located)."""

    def __init__(self, motion: MotionDetector, model: AppearanceModel, every: int,
                 motion_blobs: bool = True, threaded: bool = True, alone_score: float = 0.0,
                 windows: list[Window] | None = None) -> None:
        """`motion_blobs` False: appearance alone (kind "appearance"); `threaded` False:
        each pass runs when its frame is located, in the caller's thread (--profile);
        `alone_score`: fusion.fuse's; `windows`: the tiles looked at in turn half-way
        between two whole-frame passes (none: whole-frame passes only)."""
        self.motion = motion
        self.alone_score = alone_score
        self.model = model
        self.every = max(1, every)
        self.windows = list(windows or [])
        self.motion_blobs = motion_blobs
        self._pool = (ThreadPoolExecutor(max_workers=1, thread_name_prefix="vtrack-appearance",
                                         initializer=yield_to_the_pipeline)
                      if threaded else None)
        self._pending: deque[Future | np.ndarray | None] = deque()
        self._requested = 0
        self._riders = Fused.empty()

    def __getattr__(self, name: str) -> Any:
        """The image stages and their state (prepare, align, subtract, segment, initialise,
        frames, scale, foreground, ...) are the motion detector's."""
        return getattr(self.motion, name)

    def scheduled(self, number: int) -> bool:
        """Whether frame `number` (1-based, in reading order) gets an appearance pass."""
        return (number - 1) % self.every == 0 or self._tile_pass(number) is not None

    def _tile_pass(self, number: int) -> int | None:
        """The index of the tile pass of frame `number`, if it has one: half-way between
        two whole-frame passes (on every other pass where every frame has one)."""
        if not self.windows:
            return None
        if self.every == 1:
            return (number - 1) // 2 if number % 2 == 0 else None
        phase = (number - 1) % self.every
        return (number - 1) // self.every if phase == self.every // 2 else None

    def view(self, number: int) -> Window | None:
        """The window the pass of scheduled frame `number` looks at: a tile, in turn, half-way
        between the whole-frame passes; None: the whole frame."""
        k = self._tile_pass(number)
        return None if k is None else self.windows[k % len(self.windows)]

    def request(self, image: np.ndarray) -> None:
        """The next frame's full-resolution image, as it is read: its pass starts now if the
        schedule picks it."""
        self._requested += 1
        job: Future | tuple[np.ndarray, Window | None] | None = None
        if self.scheduled(self._requested):
            window = self.view(self._requested)
            job = ((image, window) if self._pool is None
                   else self._pool.submit(self.model.detect, image, window))
        self._pending.append(job)

    def detect(self, image: np.ndarray, predicted: np.ndarray | None = None) -> Detections:
        """One frame: request, segment and locate."""
        self.request(image)
        return self.locate(self.motion.segment(image), predicted)

    def locate(self, fg: Foreground, predicted: np.ndarray | None = None) -> Detections:
        """The frame's fused detections (fusion.py), in its pixels."""
        dets = self.motion.locate(fg, predicted)
        if not self.motion_blobs:
            dets = Detections.empty(dets.motion)
        job = self._pending.popleft() if self._pending else None
        if job is not None:
            app = job.result() if isinstance(job, Future) else self.model.detect(*job)
            app = app.take(self.motion.in_roi(centre(app.boxes)))   # the user's ROI only
            f = renew(self._riders, dets.boxes, dets.areas, app, self.alone_score)
        else:   # between passes: the boxes ride on their blobs or stand
            f = follow(self._riders, dets.boxes, dets.areas)
        self._riders = f.riders()
        return Detections(centre(f.boxes), f.boxes, f.areas, dets.motion, dets.changed,
                          source=f.source, score=f.score, cls=f.cls)

    def close(self) -> None:
        """Stop the worker (a pass under way finishes first)."""
        for job in self._pending:
            if isinstance(job, Future):
                job.cancel()
        self._pending.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=True)


def make_detector(cfg: DetectorConfig, width: int, height: int, fps: float = 25.0,
                  roi: np.ndarray | None = None, threaded: bool = True
                  ) -> MotionDetector | FusedDetector:
    """The detector `cfg.kind` names: MOG2 alone, appearance alone or both fused
    (`threaded`: FusedDetector's)."""
    motion = MotionDetector(cfg, width, height, fps, roi,
                            far=cfg.kind == "hybrid" and cfg.far_band)
    if cfg.kind == "mog2":
        return motion
    model = AppearanceModel(cfg.appearance_model or None, min_score=cfg.appearance_score)
    every = 1 if cfg.kind == "appearance" else max(1, round(cfg.appearance_seconds * fps))
    hybrid = cfg.kind == "hybrid"
    windows = tiles(width, height, model.side) if hybrid and cfg.appearance_tiles else []
    return FusedDetector(motion, model, every, motion_blobs=hybrid, threaded=threaded,
                         alone_score=cfg.appearance_alone_score if hybrid else 0.0,
                         windows=windows)
