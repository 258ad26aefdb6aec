"""Rerun recordings are real .rrd files: read them back and check what they hold."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

from vtrack.cli import main  # noqa: E402
from vtrack.evaluation.mot import read_mot  # noqa: E402


def _columns(path, entity: str, component: str) -> list[tuple[int, np.ndarray]]:
    """(frame, values) of one component of one entity, over all chunks."""
    out = []
    for ch in RrdReader(str(path)).stream():
        if ch.entity_path != entity:
            continue
        rb = ch.to_record_batch()
        if component not in rb.schema.names or "frame" not in rb.schema.names:
            continue
        frames = rb.column("frame").to_pylist()
        values = rb.column(component).to_pylist()
        out.extend((f, np.array(v, dtype=float)) for f, v in zip(frames, values) if v)
    return sorted(out, key=lambda fv: fv[0])


def test_track_recording_holds_frames_tracks_and_series(synth_video, tmp_path):
    rrd = tmp_path / "run.rrd"
    out = tmp_path / "out"
    assert main(["track", str(synth_video(0) / "video.avi"), "--out", str(out), "--quiet",
                 "--max-frames", "100", "--rerun", str(rrd)]) == 0
    entities = {ch.entity_path for ch in RrdReader(str(rrd)).stream()}
    for e in ("/camera/image", "/camera/detections", "/metrics/tracks"):
        assert e in entities
    assert any(e.startswith("/camera/tracks/") for e in entities)
    assert any(e.startswith("/camera/covariance/") for e in entities)
    assert any(e.startswith("/tracks/") and e.endswith("/speed") for e in entities)
    images = _columns(rrd, "/camera/image", "EncodedImage:blob")
    assert [f for f, _ in images] == list(range(1, 101))
    rows = read_mot(out / "tracks.csv")
    tid = int(np.bincount(rows[:, 1].astype(int)).argmax())   # the longest track
    mine = rows[rows[:, 1] == tid]
    logged = _columns(rrd, f"/camera/tracks/{tid}", "Boxes2D:centers")
    assert [f for f, _ in logged] == mine[:, 0].astype(int).tolist()
    centers = np.array([v.reshape(-1, 2)[0] for _, v in logged])
    expected = mine[:, 2:4] + mine[:, 4:6] / 2
    np.testing.assert_allclose(centers, expected, atol=0.01)   # tracks.csv keeps 2 decimals


def test_no_rerun_import_without_the_flag(synth_video, tmp_path):
    code = ("import sys; from vtrack.cli import main; "
            f"main(['track', {str(synth_video(0) / 'video.avi')!r}, '--out', "
            f"{str(tmp_path)!r}, '--quiet', '--max-frames', '5']); "
            "print('rerun' in sys.modules)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert res.stdout.strip() == "False"


def test_experiment_recording(tmp_path):
    rrd = tmp_path / "exp.rrd"
    assert main(["experiment", "bearings-3", "--runs", "2", "--rerun", str(rrd)]) == 0
    entities = {ch.entity_path for ch in RrdReader(str(rrd)).stream()}
    assert "/plane/truth" in entities and "/plane/sensors" in entities
    assert {"/error/ekf", "/error/ukf", "/error/ckf"} <= entities
    assert any(e.endswith("/ellipse") for e in entities)
