"""Axis-aligned box geometry shared by the detector, the tracker and the evaluation: boxes
are (..., 4) arrays (left, top, width, height) in pixels."""

from __future__ import annotations

import numpy as np


def intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection areas of boxes a and b, broadcast over their leading axes."""
    w = np.minimum(a[..., 0] + a[..., 2], b[..., 0] + b[..., 2]) - np.maximum(a[..., 0], b[..., 0])
    h = np.minimum(a[..., 1] + a[..., 3], b[..., 1] + b[..., 3]) - np.maximum(a[..., 1], b[..., 1])
    return np.clip(w, 0, None) * np.clip(h, 0, None)


def overlap_of_smaller(box: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Intersection area of `box` (4,) with each of `others` (n, 4) over the smaller of the
    two areas."""
    smaller = np.minimum(box[2] * box[3], others[:, 2] * others[:, 3])
    return intersection(box, others) / np.maximum(smaller, 1e-9)


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU matrix (n, m) between boxes a (n, 4) and b (m, 4)."""
    inter = intersection(a[:, None], b[None])
    return inter / (a[:, None, 2] * a[:, None, 3] + b[None, :, 2] * b[None, :, 3] - inter)
