"""Detector stage: foreground that has not changed for long is a ghost (`static_seconds`).

MOG2 shows a ghost wherever its model holds something the scene no longer shows: a vehicle
baked into the background estimated from the first seconds (a slow truck convoy: the
median of the samples is smeared trucks, and the road there is foreground until MOG2 has
relearnt it at 1 / history, ~20 s), or a vehicle that stood until it melted in and then
drove off. A ghost does not change from frame to frame; the blob motion test
(blobs.BlobTests) drops a ghost alone, but not one that touches a moving vehicle, which
then carries the ghost in its blob (one blob for a truck, the road around it and the cars
beside it).

Per pixel, the number of consecutive frames it has been foreground without changing
(the motion map's test: no channel moved by more than blobs.MOTION_DIFF over
blobs.MOTION_GAP frames) is counted; foreground that has stood still for more than
`frames` is dropped from the mask, except inside the `exempt` mask (standing vehicles
held out of the model on purpose, hold.py). A moving vehicle covers a pixel with one
colour for as long as a uniform part of it passes over the pixel (a long trailer at walking
pace: seconds), so `frames` must be longer than that.
"""

from __future__ import annotations

import numpy as np


class StaticForeground:
    """How long each foreground pixel has stood unchanged; drops those over `frames`."""

    def __init__(self, frames: int) -> None:
        self.frames = frames
        self._age: np.ndarray | None = None

    def __call__(self, fg: np.ndarray, changed: np.ndarray | None,
                 exempt: np.ndarray | None = None) -> np.ndarray:
        """`fg` (0/255) less the pixels that have been foreground and unchanged (`changed`
        0/1, None: everything changed) for more than `frames` frames and are not in
        `exempt` (0/255)."""
        if self._age is None or self._age.shape != fg.shape:
            self._age = np.zeros(fg.shape, np.uint16)
        still = fg > 0
        if changed is not None:
            still &= changed == 0
        else:
            still[:] = False
        self._age = np.where(still, np.minimum(self._age, 65534) + 1, 0).astype(np.uint16)
        ghost = self._age > self.frames
        if exempt is not None:
            ghost &= exempt == 0
        if not ghost.any():
            return fg
        out = fg.copy()
        out[ghost] = 0
        return out
