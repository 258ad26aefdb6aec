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
    return paired_iou(a[:, None], b[None])


def paired_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of boxes a and b, broadcast over their leading axes (a[i] with b[i])."""
    inter = intersection(a, b)
    return inter / np.maximum(a[..., 2] * a[..., 3] + b[..., 2] * b[..., 3] - inter, 1e-9)


def enclosing(boxes: np.ndarray) -> np.ndarray:
    """The box (4,) around boxes (n >= 1, 4)."""
    x0, y0 = boxes[:, :2].min(axis=0)
    x1, y1 = (boxes[:, :2] + boxes[:, 2:]).max(axis=0)
    return np.array([x0, y0, x1 - x0, y1 - y0])


def enclosing_each(boxes: np.ndarray, member: np.ndarray) -> np.ndarray:
    """(n, 4): for each row of `member` (n, B) bool, the box around the boxes (B, 4) it
    selects (`enclosing` of each; a row must select one at least)."""
    chosen = member[:, :, None]
    ends = boxes[:, :2] + boxes[:, 2:]
    lo = np.where(chosen, boxes[None, :, :2], np.inf).min(axis=1, initial=np.inf)
    hi = np.where(chosen, ends[None], -np.inf).max(axis=1, initial=-np.inf)
    return np.concatenate([lo, hi - lo], axis=1)


def clip(boxes: np.ndarray, width: float, height: float) -> np.ndarray:
    """Boxes (n, 4) cut to the image [0, width] x [0, height] (may become empty)."""
    cut = np.clip(edges(boxes), 0, (width, height, width, height))   # x0, y0, x1, y1
    return np.concatenate([cut[:, :2], cut[:, 2:] - cut[:, :2]], axis=1)


def centre(boxes: np.ndarray) -> np.ndarray:
    """(..., 2) centres of boxes (..., 4)."""
    return boxes[..., :2] + boxes[..., 2:] / 2


def contains(boxes: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, K) whether box i (N, 4) holds point k (K, 2), left and top edges included,
    right and bottom excluded."""
    x, y = points[None, :, 0], points[None, :, 1]
    return ((x >= boxes[:, None, 0]) & (x < boxes[:, None, 0] + boxes[:, None, 2])
            & (y >= boxes[:, None, 1]) & (y < boxes[:, None, 1] + boxes[:, None, 3]))


def edges(boxes: np.ndarray) -> np.ndarray:
    """(..., 4) edges x0, y0, x1, y1 of boxes (..., 4) x, y, w, h."""
    return np.concatenate([boxes[..., :2], boxes[..., :2] + boxes[..., 2:]], axis=-1)


def from_edges(e: np.ndarray) -> np.ndarray:
    """(..., 4) boxes x, y, w, h of edges x0, y0, x1, y1 (..., 4): the inverse of `edges`."""
    return np.concatenate([e[..., :2], e[..., 2:] - e[..., :2]], axis=-1)


def from_centre(centres: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """(..., 4) boxes x, y, w, h of the given centres (..., 2) and sizes (..., 2)."""
    return np.concatenate([centres - sizes / 2, sizes], axis=-1)


def scale(boxes: np.ndarray) -> np.ndarray:
    """(...,) box scale sqrt(w h), px: the unit of the tracker's scale-free parameters."""
    return np.sqrt(boxes[..., 2] * boxes[..., 3])


def in_image(boxes: np.ndarray, width: float, height: float) -> np.ndarray:
    """(...,) whether each box (..., 4) lies wholly inside the image [0, width] x [0, height]."""
    return ((boxes[..., 0] >= 0) & (boxes[..., 1] >= 0)
            & (boxes[..., 0] + boxes[..., 2] <= width) & (boxes[..., 1] + boxes[..., 3] <= height))


def on_border(boxes: np.ndarray, width: float, height: float, tol: float = 0.5
              ) -> np.ndarray:
    """(K, 2, 2): which edges (axis x, y; low, high) of boxes (K, 4) lie on the image
    border, within `tol` px: where a vehicle may go on beyond the picture."""
    lo, hi = boxes[:, :2], boxes[:, :2] + boxes[:, 2:]
    return np.stack([lo <= tol, hi >= np.array([width, height]) - tol], axis=2)
