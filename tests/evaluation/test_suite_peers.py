"""The scene suite's peers, SORT and ByteTrack of the `trackers` package (scripts/eval_suite.py
`peer_rows`), run on a tiny set of detections: two cars crossing the picture in opposite
directions. Each peer must follow both with one id each (the suite compares vtrack with
them, so a peer that silently stopped tracking would make vtrack look good)."""

from __future__ import annotations

import numpy as np
import pytest

from vtrack.evaluation.mot import evaluate_arrays

FRAMES, FPS = 40, 25.0


def _truth() -> np.ndarray:
    """MOT rows (frame, id, x, y, w, h, 1, -1, -1, -1) of two 60 x 30 cars at 150 px/s."""
    rows = []
    for n in range(1, FRAMES + 1):
        t = (n - 1) / FPS
        rows.append((n, 1, 40 + 150 * t, 100, 60, 30))
        rows.append((n, 2, 500 - 150 * t, 200, 60, 30))
    out = np.array(rows, dtype=float)
    return np.hstack([out, np.tile([1.0, -1.0, -1.0, -1.0], (len(out), 1))])


@pytest.mark.parametrize("peer", ["sort", "bytetrack"])
def test_peer_tracks_two_cars(load_script, peer) -> None:
    pytest.importorskip("trackers")
    suite = load_script("eval_suite")
    gt = _truth()
    dets = gt.copy()
    dets[:, 1] = -1
    rows = suite.peer_rows(peer, dets, FRAMES, FPS)
    assert rows.shape[1] == 6 and len(rows)
    assert len(np.unique(rows[:, 1])) == 2
    mot = np.hstack([rows, np.tile([1.0, -1.0, -1.0, -1.0], (len(rows), 1))])
    scores = evaluate_arrays(gt, mot)
    print(f"{peer}: MOTA {scores['mota']:.3f} IDF1 {scores['idf1']:.3f}")
    assert scores["id_switches"] == 0
    assert scores["false_positives"] == 0
    assert scores["mota"] >= 0.9    # a peer may take a few frames to start a track


def test_appearance_peer_starts_tracks_on_yolox_nano_scores(load_script) -> None:
    """The YOLOX + ByteTrack peer's thresholds (eval_suite.APPEARANCE_BYTETRACK) start tracks
    on boxes scored like YOLOX-Nano's (0.45); at the package's defaults (0.7 to start a
    track) ByteTrack starts none, which is why the suite sets them."""
    pytest.importorskip("trackers")
    suite = load_script("eval_suite")
    dets = _truth()
    dets[:, 1], dets[:, 6] = -1, 0.45
    tuned = suite.peer_rows("bytetrack", dets, FRAMES, FPS, **suite.APPEARANCE_BYTETRACK)
    assert len(np.unique(tuned[:, 1])) == 2 and len(tuned) >= 2 * (FRAMES - 5)
    assert len(suite.peer_rows("bytetrack", dets, FRAMES, FPS)) == 0
