"""Detector output: how much of a region MOG2 saw change.

A tracker that holds one blob as two pieces has to tell two vehicles one behind the other
from one vehicle seen in two pieces. The gap between the pieces says which. Between two
vehicles it is road, and MOG2 leaves it unlabelled apart from a cast shadow. Inside a
vehicle it is body, and MOG2 labels that foreground or, for a body darker than the road,
shadow (127). The shadow stage (shadows.py) then drops the shadow-labelled body because its
texture is the road's dimmed, so the cleaned mask alone cannot tell the two gaps apart.

`ChangedMap` answers, for boxes in the frame's pixels, the share of their pixels that MOG2
labelled foreground or shadow, read from MOG2's raw mask before any later stage.
"""

from __future__ import annotations

import numpy as np

from vtrack.vision.stabilise import onto_mask


class ChangedMap:
    """The share of each box's pixels that MOG2 labelled foreground or shadow."""

    def __init__(self, labels: np.ndarray, sx: float, sy: float, camera: np.ndarray) -> None:
        """labels: MOG2's raw mask (HxW: 0 background, 127 shadow, 255 foreground) at the
        detection resolution, in the stabiliser's reference pixels; (sx, sy): full-resolution
        pixels per mask pixel; camera (2, 3): the reference -> this frame, full resolution."""
        self.labels = labels
        self.sx, self.sy = sx, sy
        self.camera = camera

    def __call__(self, boxes: np.ndarray) -> np.ndarray:
        """(K,) share of changed pixels in boxes (K, 4), x, y, w, h in this frame's pixels:
        each box is mapped into the mask and widened to whole mask pixels; nan for a box
        that covers no mask pixel."""
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        m = onto_mask(boxes, self.camera, self.sx, self.sy)
        h, w = self.labels.shape[:2]
        x0, y0 = np.floor(m[:, :2]).astype(int).T
        x1, y1 = np.ceil(m[:, :2] + m[:, 2:]).astype(int).T
        x0, x1 = np.clip(x0, 0, w), np.clip(x1, 0, w)
        y0, y1 = np.clip(y0, 0, h), np.clip(y1, 0, h)
        share = np.full(len(boxes), np.nan)
        for k in np.flatnonzero((x1 > x0) & (y1 > y0)):
            region = self.labels[y0[k]:y1[k], x0[k]:x1[k]]
            share[k] = np.count_nonzero(region) / region.size
        return share
