"""Detector stage: shadows out of the foreground mask."""

from __future__ import annotations

import cv2
import numpy as np


def drop_shadows(raw: np.ndarray, threshold: int) -> np.ndarray:
    """Binary mask (0/255) of the mask values >= threshold: MOG2 labels shadow pixels 127,
    so the default threshold 200 drops them."""
    return cv2.threshold(raw, threshold - 1, 255, cv2.THRESH_BINARY)[1]
