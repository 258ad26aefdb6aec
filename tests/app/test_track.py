"""End to end: synthetic video -> vtrack track -> vtrack eval, real clips' line counts,
outputs, interruption and bad input."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from vtrack.cli import main
from vtrack.evaluation.mot import box_iou, evaluate, read_mot


def _track(video: Path, out: Path, *extra: str) -> dict:
    assert main(["track", str(video), "--out", str(out), "--quiet", *extra]) == 0
    return json.loads((out / "summary.json").read_text())


# seed: (MOTA, IDF1) measured with the default configuration on the commit that set these
# floors (before, one floor for all: MOTA 0.85, IDF1 0.80). The run is deterministic; the
# floors sit ACCURACY_MARGIN below, for changes elsewhere that move a box or two (a real
# regression of the tracker costs more).
ACCURACY = {0: (0.975, 0.960), 1: (0.996, 0.998), 2: (0.865, 0.870)}
ACCURACY_MARGIN = 0.025


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_synthetic_accuracy(synth_video, tmp_path, seed):
    src = synth_video(seed)
    _track(src / "video.avi", tmp_path)
    scores = evaluate(src / "gt.csv", tmp_path / "tracks.csv")
    print(f"seed {seed}: {scores}")
    mota, idf1 = ACCURACY[seed]
    assert scores["mota"] >= mota - ACCURACY_MARGIN
    assert scores["idf1"] >= idf1 - ACCURACY_MARGIN


def test_vehicle_behind_occluder_keeps_its_id(synth_video, tmp_path):
    src = synth_video(0)
    _track(src / "video.avi", tmp_path)
    gt = read_mot(src / "gt.csv")
    tr = read_mot(tmp_path / "tracks.csv")
    checked = 0
    for gid in np.unique(gt[:, 1]):
        g = gt[gt[:, 1] == gid]
        at_border = ((g[:, 2] <= 0) | (g[:, 3] <= 0) | (g[:, 2] + g[:, 4] >= 640)
                     | (g[:, 3] + g[:, 5] >= 360))
        g = g[~at_border]   # entering or leaving the image is not an occlusion
        if len(g) == 0:
            continue
        vis = g[:, 10]
        hidden = np.flatnonzero(vis < 0.3)
        before = np.flatnonzero((vis > 0.9) & (np.arange(len(g)) < (hidden.min() if len(hidden) else 0)))
        after = np.flatnonzero((vis > 0.9) & (np.arange(len(g)) > (hidden.max() if len(hidden) else 0)))
        if len(hidden) < 3 or len(before) < 5 or len(after) < 5:
            continue  # not occluded mid-path for several frames

        def matched_id(row):
            cand = tr[tr[:, 0] == row[0]]
            if len(cand) == 0:
                return None
            iou = box_iou(row[None, 2:6], cand[:, 2:6])[0]
            return int(cand[np.argmax(iou), 1]) if iou.max() >= 0.5 else None

        id_before = matched_id(g[before[-1]])
        # the first id matched to it within 10 frames of coming out from behind the occluder
        id_after = next((i for i in map(matched_id, g[after[:10]]) if i is not None), None)
        assert id_before is not None and id_before == id_after, f"gt vehicle {gid}"
        checked += 1
    assert checked >= 1, "the synthetic clip should contain a vehicle hidden by the occluder"


def test_outputs_follow_the_interface(synth_video, tmp_path):
    src = synth_video(0)
    summary = _track(src / "video.avi", tmp_path, "--max-frames", "120", "--save-frames",
                     "--count-line", "320,0,320,360")
    rows = read_mot(tmp_path / "tracks.csv")
    assert summary["frames"] == 120 and summary["complete"] is True
    assert summary["tracks"] == len(np.unique(rows[:, 1]))
    assert {"video", "width", "height", "fps_video", "fps_processed", "counts"} <= set(summary)
    order = np.lexsort((rows[:, 1], rows[:, 0]))
    assert np.array_equal(order, np.arange(len(rows))), "rows sorted by frame then id"
    assert np.all(rows[:, 6] > 0) and np.all(rows[:, 6] <= 1)
    assert np.all(rows[:, 7:10] == -1)
    frames = sorted((tmp_path / "frames").iterdir())
    assert len(frames) == 120 and frames[0].name == "000001.jpg"
    crossings = (tmp_path / "crossings.csv").read_text().splitlines()
    assert crossings[0] == "frame,time_s,id,line,direction"
    c = summary["counts"][0]
    assert c["line"] == [320.0, 0.0, 320.0, 360.0]
    assert c["forward"] + c["backward"] == c["total"] == len(crossings) - 1
    # a re-run without --save-frames leaves no stale frames behind
    _track(src / "video.avi", tmp_path, "--max-frames", "20")
    assert not (tmp_path / "frames").exists()


def test_save_detections_writes_the_detector_boxes(synth_video, tmp_path):
    """--save-detections: MOT detection rows of every frame; each detected track row lies
    on one of its frame's detections (the peers of scripts/eval_suite.py track these)."""
    src = synth_video(0)
    _track(src / "video.avi", tmp_path, "--max-frames", "80", "--save-detections")
    dets = np.loadtxt(tmp_path / "detections.csv", delimiter=",", ndmin=2)
    rows = read_mot(tmp_path / "tracks.csv")
    assert len(dets) > 0 and np.all(dets[:, 1] == -1) and np.all(dets[:, 4:6] > 0)
    assert 1 <= dets[:, 0].min() and dets[:, 0].max() <= 80
    detected = rows[rows[:, 6] == 1.0]
    assert len(detected) > 0
    for r in detected:
        same = dets[dets[:, 0] == r[0]]
        assert len(same) and box_iou(r[None, 2:6], same[:, 2:6]).max() > 0


@pytest.mark.parametrize("clip,lines,expected", [
    ("highway", (0.6, 0.8), 27),
    ("residential", (0.6,), 3),
])
def test_real_clip_line_counts_match_hand_counts(tmp_path, real_clip, clip, lines, expected):
    import cv2

    video = real_clip(clip)
    cap = cv2.VideoCapture(str(video))
    w, h = cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)
    cap.release()
    args = []
    for f in lines:
        args += ["--count-line", f"0,{f * h},{w},{f * h}"]
    summary = _track(video, tmp_path, *args)
    totals = [c["total"] for c in summary["counts"]]
    print(f"{clip}: line totals {totals} vs hand count {expected}, "
          f"{summary['tracks']} tracks")
    for total in totals:
        if expected <= 3:
            assert total == expected
        else:
            assert abs(total - expected) <= 0.1 * expected


def test_interrupt_flushes_valid_files(synth_video, tmp_path, read_video, terminal_sigint):
    src = synth_video(1)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    frames = tmp_path / "frames"
    # The 250-frame run takes a few seconds: on a loaded machine this test's process can be
    # descheduled long enough for the run to end before the signal is sent. Such a try
    # (the run complete, exit 0) tested nothing, so the run is started again (at most 3
    # tries), each waiting for frames of its own (the frames of a try before are stale).
    for _ in range(3):
        shutil.rmtree(frames, ignore_errors=True)
        proc = subprocess.Popen([sys.executable, "-m", "vtrack", "track",
                                 str(src / "video.avi"), "--out", str(tmp_path), "--quiet",
                                 "--save-frames", "--save-video"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
        deadline = time.time() + 60
        while time.time() < deadline and proc.poll() is None and (
                not frames.exists() or len(list(frames.iterdir())) < 30):
            time.sleep(0.05)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        if proc.returncode != 0 or not json.loads(
                (tmp_path / "summary.json").read_text())["complete"]:
            break
    assert proc.returncode == 130, err
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["complete"] is False and 0 < summary["frames"] < 250
    rows = read_mot(tmp_path / "tracks.csv")
    assert len(rows) == 0 or rows[:, 0].max() <= summary["frames"]
    assert not list(tmp_path.glob(".*.tmp"))
    video = read_video(tmp_path / "annotated.mp4")   # finalised on the interrupt
    assert video["codec"] == "h264" and abs(video["frames"] - summary["frames"]) <= 1
    assert summary["stopped_by"] == "interrupted"


@pytest.mark.parametrize("make", ["missing", "text", "empty", "directory"])
def test_bad_video_is_one_error_line_and_writes_nothing(tmp_path, capsys, make):
    video = tmp_path / "clip.mp4"
    if make == "text":
        video.write_text("not a video\n")
    elif make == "empty":
        video.write_bytes(b"")
    elif make == "directory":
        video.mkdir()
    out = tmp_path / "out"
    assert main(["track", str(video), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "clip.mp4" in err[0]
    assert not out.exists()


def test_unknown_config_key_is_rejected(synth_video, tmp_path, capsys):
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[tracker]\nmax_coast = 3\n")
    out = tmp_path / "out"
    assert main(["track", str(synth_video(0) / "video.avi"), "--config", str(cfg),
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "max_coast" in err and err.startswith("error: ")
    assert not out.exists()


class _Recorder:
    """A detector whose `align` and `subtract` record the thread and order they run in,
    and how many frames the caller had taken when each `subtract` began."""

    def __init__(self, fail_at: int | None = None) -> None:
        self.calls: list[tuple[str, int, str]] = []
        self.fail_at = fail_at
        self.taken = 0          # frames the caller has taken from `segmented`
        self.taken_at: dict[int, int] = {}

    def _record(self, stage: str, image: int) -> None:
        import threading

        self.calls.append((stage, image, threading.current_thread().name))

    def align(self, image, prepared=False):
        self._record("align", image)
        return image

    def subtract(self, image):
        import time

        time.sleep(0.002)       # let the caller run ahead if nothing holds it back
        if image == self.fail_at:
            raise RuntimeError(f"segment failed on {image}")
        self.taken_at[image] = self.taken
        self._record("subtract", image)
        return -image


def _frames(n: int, fail_after: int | None = None):
    from types import SimpleNamespace

    from vtrack.errors import InputError

    for k in range(1, n + 1):
        yield SimpleNamespace(index=k, image=k), False
        if k == fail_after:
            raise InputError("source lost after frame %d" % k)


def test_segmented_runs_each_frame_ahead_in_a_worker_in_order():
    from vtrack.app.track import segmented

    det = _Recorder()
    out = []
    for f, fg in segmented(_frames(6), det):
        out.append((f.index, fg))
        det.taken += 1
    assert out == [(k, -k) for k in range(1, 7)]
    for stage in ("align", "subtract"):
        calls = [(k, name) for s, k, name in det.calls if s == stage]
        assert [k for k, _ in calls] == list(range(1, 7))
        assert all(name.startswith(f"vtrack-{stage}") for _, name in calls)
    # subtract of frame k begins only once the caller has finished frame k - 2 (and so
    # handed over the boxes located there: detect.HOLD_LAG), never before
    assert all(det.taken_at[k] >= k - 2 for k in range(1, 7)), det.taken_at


def test_segmented_gives_the_frame_in_hand_before_a_source_error():
    from vtrack.app.track import segmented
    from vtrack.errors import InputError

    got = []
    with pytest.raises(InputError, match="after frame 4"):
        for f, fg in segmented(_frames(9, fail_after=4), _Recorder()):
            got.append((f.index, fg))
    assert got == [(k, -k) for k in range(1, 5)]
    got.clear()   # a detector failure reaches the caller at its frame
    with pytest.raises(RuntimeError, match="failed on 3"):
        for f, _ in segmented(_frames(9), _Recorder(fail_at=3)):
            got.append(f.index)
    assert got == [1, 2]


def test_requested_asks_for_each_pass_ahead_and_keeps_the_frames_before_an_error():
    """`requested` hands each frame to the detector as it is read and passes it on
    `ahead` frames later (the pass's slack), in order; a source error still gives the
    frames read before it."""
    from types import SimpleNamespace

    from vtrack.app.track import requested
    from vtrack.errors import InputError

    asked: list[int] = []
    det = SimpleNamespace(request=asked.append)
    seen = []
    for f, _ in requested(_frames(6), det, ahead=3):
        seen.append((f.index, list(asked)))
    assert [k for k, _ in seen] == list(range(1, 7))
    assert seen[0][1] == [1, 2, 3, 4] and seen[-1][1] == list(range(1, 7))
    got = []
    with pytest.raises(InputError, match="after frame 4"):
        for f, _ in requested(_frames(9, fail_after=4), SimpleNamespace(request=id), 8):
            got.append(f.index)
    assert got == [1, 2, 3, 4]


def test_opencv_threads_during_a_run(synth_video, tmp_path, monkeypatch):
    """The run uses OpenCV with `cv_threads` threads (image stages included, in the worker
    thread) and leaves OpenCV's setting as it found it."""
    import cv2

    from vtrack.app import config
    from vtrack.app.track import TrackOptions, track_video
    from vtrack.vision.detect import MotionDetector

    seen = set()
    subtract = MotionDetector.subtract

    def spy(self, *args, **kwargs):
        seen.add(cv2.getNumThreads())
        return subtract(self, *args, **kwargs)

    monkeypatch.setattr(MotionDetector, "subtract", spy)
    before = cv2.getNumThreads()
    cv2.setNumThreads(2)
    try:
        track_video(synth_video(0) / "video.avi", tmp_path / "a", config.load(None),
                    TrackOptions(max_frames=20))
        assert seen == {1} and cv2.getNumThreads() == 2
        seen.clear()
        track_video(synth_video(0) / "video.avi", tmp_path / "b", config.load(None),
                    TrackOptions(max_frames=20, cv_threads=0))
        assert seen == {2}
    finally:
        cv2.setNumThreads(before)
