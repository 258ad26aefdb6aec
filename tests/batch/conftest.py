"""Small videos for the batch tests: cheap to make (a few moving boxes, MJPG), any count."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest


def make_video(path: Path, frames: int = 40, seed: int = 0, size: tuple[int, int] = (192, 108)
               ) -> Path:
    """A textured road with three boxes crossing it at seed-dependent speeds."""
    import cv2

    w, h = size
    rng = np.random.default_rng(seed)
    background = rng.integers(70, 110, (h, w, 3), dtype=np.uint8)
    background = cv2.GaussianBlur(background, (5, 5), 0)
    boxes = [(rng.uniform(-30, 0), 10 + 32 * k, rng.uniform(1.5, 3.0), rng.integers(0, 255, 3))
             for k in range(3)]
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter_fourcc(*"MJPG"),
                             25.0, (w, h))
    assert writer.isOpened()
    for n in range(frames):
        img = background.copy()
        for x0, y, v, colour in boxes:
            x = int(x0 + v * n)
            x = x % (w + 40) - 40   # wrap around: long clips keep moving boxes
            cv2.rectangle(img, (x, int(y)), (x + 24, int(y) + 14),
                          tuple(int(c) for c in colour), -1)
        writer.write(img)
    writer.release()
    return path


@pytest.fixture(scope="session")
def clip_factory(tmp_path_factory):
    """(frames, seed) -> a cached video file; copy it where a test needs it."""
    cache: dict[tuple[int, int], Path] = {}
    root = tmp_path_factory.mktemp("batch-clips")

    def get(frames: int = 40, seed: int = 0) -> Path:
        key = (frames, seed)
        if key not in cache:
            cache[key] = make_video(root / f"clip_{frames}_{seed}.avi", frames, seed)
        return cache[key]

    return get
