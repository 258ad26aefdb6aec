"""The MJPEG AVI writer: OpenCV reads back every frame, the frame rate and the size."""

from __future__ import annotations

import cv2
import numpy as np

from vtrack.sim.avi import write_mjpeg_avi


def test_avi_reads_back_frames_rate_and_size(tmp_path):
    rng = np.random.default_rng(0)
    frames = [cv2.GaussianBlur(rng.integers(0, 255, (90, 160, 3), dtype=np.uint8), (0, 0), 6)
              for _ in range(7)]
    path = tmp_path / "clip.avi"
    assert write_mjpeg_avi(path, iter(frames), 160, 90, 12.5, 95) == 7
    cap = cv2.VideoCapture(str(path))
    assert cap.get(cv2.CAP_PROP_FPS) == 12.5
    read = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        read.append(frame)
    assert len(read) == 7 and read[0].shape == (90, 160, 3)
    for a, b in zip(frames, read):
        assert np.abs(a.astype(int) - b.astype(int)).mean() < 2.0
    assert [p.name for p in tmp_path.iterdir()] == ["clip.avi"]       # no temporary left
