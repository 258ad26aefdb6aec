"""The detector's background estimated from the tracking's own read of the video.

The background is estimated from `init_background_samples` frames spread evenly over the
first `init_background_seconds` of the video (`sample_numbers`), before the first frame is
tracked. `read_once` takes them from the one decoding the run tracks: it reads ahead to the
last sampled frame, keeps each frame it read at the detection resolution (the detector's
`prepare`, a function of the frame alone), starts the background from the sampled ones and
then hands on the frames it kept followed by the rest of the video, so the detector sees
the same images in the same order as it would from a second read of the video's start,
without decoding that start twice. The frames kept cost memory: at most
`LOOKAHEAD_BYTES` (`fits`); a run that needs the full frames later (annotation, a rerun
recording) or a longer look-ahead reads the start a second time instead (app/track.py).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import AbstractContextManager
from typing import Any

from vtrack.errors import InputError
from vtrack.io.video import Frame

LOOKAHEAD_BYTES = 256 << 20   # frames kept at the detection resolution while reading ahead


def sample_numbers(fps: float, frame_count: int, max_frames: int | None, seconds: float,
                   samples: int) -> set[int]:
    """Numbers (1-based) of the frames sampled for the background: `samples` frames evenly
    over the first n = min(round(seconds x fps), frame_count, max_frames) frames, frame
    1 + floor(k n / samples) for k = 0 .. samples - 1; none when n < samples."""
    n = round(seconds * fps)
    if frame_count:
        n = min(n, frame_count)
    if max_frames:
        n = min(n, max_frames)
    if n < samples:
        return set()
    stride = n / samples
    return {1 + int(k * stride) for k in range(samples)}


def fits(wanted: set[int], prepared_size: tuple[int, int]) -> bool:
    """Whether the frames up to the last sampled one, kept at the detection resolution
    (width, height, 3 bytes a pixel), fit in LOOKAHEAD_BYTES."""
    width, height = prepared_size
    return max(wanted, default=0) * width * height * 3 <= LOOKAHEAD_BYTES


def read_once(frames: Iterable[Frame], detector: Any, wanted: set[int],
              estimating: Callable[[], AbstractContextManager[Any]]
              ) -> Iterator[tuple[Frame, bool]]:
    """(frame, prepared) for every frame of `frames`, in order, with the background of
    `detector` (a MotionDetector) started from the frames numbered in `wanted` before the
    first is handed on. prepared: the frame's image is already `detector.prepare`d (the
    frames read ahead; their full-resolution images are not kept). A source that fails
    while reading ahead (InputError) gives the background of the frames read, those
    frames, then the error. `estimating()` is entered around the estimate (profiling)."""
    it = iter(frames)
    ahead: deque[Frame] = deque()
    failure: InputError | None = None
    if wanted:
        last = max(wanted)
        try:
            for frame in it:
                ahead.append(Frame(frame.index, frame.time, detector.prepare(frame.image)))
                if frame.index >= last:
                    break
        except InputError as exc:
            failure = exc
        with estimating():
            detector.initialise([f.image for f in ahead if f.index in wanted], prepared=True)
    while ahead:
        yield ahead.popleft(), True
    if failure is not None:
        raise failure
    for frame in it:
        yield frame, False
