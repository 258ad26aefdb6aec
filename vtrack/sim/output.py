"""What every synthetic scene writes: the settings check, gt.csv rows and the MJPG video."""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from vtrack.errors import InputError


def check_settings(frames: int, vehicles: int, width: int, height: int, fps: float,
                   seed: int, quality: int) -> None:
    """Raise InputError for settings the scene cannot be drawn with."""
    rules = [
        (frames >= 1, f"--frames must be >= 1 (got {frames})"),
        (vehicles >= 0, f"--vehicles must be >= 0 (got {vehicles})"),
        (160 <= width <= 4096, f"--width must be 160..4096 (got {width})"),
        (90 <= height <= 4096, f"--height must be 90..4096 (got {height})"),
        (math.isfinite(fps) and 1 <= fps <= 240, f"--fps must be 1..240 (got {fps})"),
        (seed >= 0, f"--seed must be >= 0 (got {seed})"),
        (1 <= quality <= 100, f"--quality must be 1..100 (got {quality})"),
    ]
    for ok, message in rules:
        if not ok:
            raise InputError(message)


def format_gt(rows: np.ndarray) -> str:
    """gt.csv text: integers as integers, the visible fraction with 4 decimals."""
    return "".join(f"{int(r[0])},{int(r[1])},{int(r[2])},{int(r[3])},{int(r[4])},{int(r[5])},"
                   f"1,-1,-1,-1,{r[10]:.4f}\n" for r in rows)


def write_video(path: Path, frames: Iterator[np.ndarray], width: int, height: int,
                fps: float, quality: int) -> None:
    """Encode MJPG into a temporary sibling, then rename it over `path`."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)           # mkstemp makes 0600; give the usual mode
    try:
        writer = cv2.VideoWriter(tmp, cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter_fourcc(*"MJPG"),
                                 fps, (width, height))
        if not writer.isOpened():
            raise InputError(f"{path}: cannot open an MJPG video writer")
        writer.set(cv2.VIDEOWRITER_PROP_QUALITY, quality)
        try:
            for frame in frames:
                writer.write(frame)
        finally:
            writer.release()
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
