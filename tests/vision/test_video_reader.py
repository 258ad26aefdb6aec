"""VideoReader on files (decoding in a supervised child), FrameClock and probe."""

from __future__ import annotations

import math
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from vtrack.errors import InputError
from vtrack.io.video import ABORT_HOOK_ENV, FrameClock, VideoReader, probe

VIDEOS = Path(__file__).resolve().parents[2].parent / "shared" / "videos"
HIGHWAY = VIDEOS / "bgslibrary_video03_highway.avi"
RESIDENTIAL = VIDEOS / "vehicle_counting_tf_sub-1504614469486_residential.mp4"
N_FRAMES, FPS, W, H = 40, 20.0, 96, 64


def _marked(n: int) -> np.ndarray:
    """Frame n (1-based) of the test clip: grey level 5 n, so order is checkable."""
    return np.full((H, W, 3), 5 * n, np.uint8)


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("video") / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), FPS, (W, H))
    for n in range(1, N_FRAMES + 1):
        writer.write(_marked(n))
    writer.release()
    return path


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_reads_every_frame_in_order_with_times(clip):
    with VideoReader(clip) as reader:
        assert reader.info.width == W and reader.info.height == H
        assert reader.info.fps == pytest.approx(FPS)
        assert reader.info.frame_count == N_FRAMES
        frames = list(reader)
    assert [f.index for f in frames] == list(range(1, N_FRAMES + 1))
    assert reader.frames_read == N_FRAMES
    levels = [float(f.image.mean()) for f in frames]
    assert levels == pytest.approx([5 * n for n in range(1, N_FRAMES + 1)], abs=2)
    times = np.array([f.time for f in frames])
    assert times[0] == 0.0
    assert np.diff(times) == pytest.approx(np.full(N_FRAMES - 1, 1 / FPS), abs=1e-3)
    assert all(f.image.dtype == np.uint8 and f.image.shape == (H, W, 3) for f in frames)


def test_max_frames_stops_early(clip):
    with VideoReader(clip, max_frames=7) as reader:
        assert [f.index for f in reader] == list(range(1, 8))
    with pytest.raises(InputError, match="max frames"):
        VideoReader(clip, max_frames=0)


def test_keep_hands_over_only_the_numbered_frames_with_their_numbers_and_times(clip):
    keep = [3, 1, 17, 40, 17]   # unsorted, repeated: each frame once, in order
    with VideoReader(clip, keep=keep) as reader:
        frames = list(reader)
    assert [f.index for f in frames] == [1, 3, 17, 40]
    assert [float(f.image.mean()) for f in frames] == pytest.approx([5, 15, 85, 200], abs=2)
    assert [f.time for f in frames] == pytest.approx([0, 2 / FPS, 16 / FPS, 39 / FPS],
                                                     abs=1e-3)
    # The same images as a full read; a number past the end ends the read there.
    with VideoReader(clip) as reader:
        full = {f.index: f.image for f in reader}
    with VideoReader(clip, keep=[5, 30, N_FRAMES + 10]) as reader:
        tail = list(reader)
    assert [f.index for f in tail] == [5, 30]
    assert all(np.array_equal(f.image, full[f.index]) for f in tail)
    with VideoReader(clip, keep=[2]) as reader:   # a first frame not kept: skipped
        assert [f.time for f in reader] == pytest.approx([1 / FPS], abs=1e-3)
    with pytest.raises(ValueError, match="keep"):
        VideoReader(clip, keep=[0, 3])


def test_frame_clock_falls_back_on_bogus_positions():
    clock = FrameClock(60.0)
    # An AVI as OpenCV reports it: two frames ahead, 0 after the last frame.
    times = [clock(p) for p in (33.3, 50.0, 66.7, 83.3, 0.0)]
    assert times == pytest.approx([0, 1 / 60, 2 / 60, 3 / 60, 4 / 60], abs=1e-3)
    clock = FrameClock(float("nan"))  # no usable fps: 25
    times = [clock(p) for p in (0.0, 40.0, 1e9, 120.0, float("nan"), 200.0)]
    assert np.all(np.diff(times) > 0)
    assert np.diff(times) == pytest.approx([0.04] * 5)
    clock = FrameClock(25.0)  # a genuine dropped frame (2 periods) is kept
    assert [clock(p) for p in (0.0, 40.0, 120.0)] == pytest.approx([0, 0.04, 0.12])
    clock = FrameClock(25.0)  # frames skipped on purpose: bounds and fall-back scale
    assert [clock(p, s) for p, s in ((80.0, 3), (320.0, 6), (0.0, 6), (1e9, 6))] == \
        pytest.approx([0.08, 0.32, 0.56, 0.80])


@pytest.mark.skipif(not HIGHWAY.exists(), reason="real clip not available")
def test_real_avi_timestamps_are_monotone_to_the_last_frame():
    with VideoReader(HIGHWAY) as reader:
        times = np.array([f.time for f in reader])
    assert reader.frames_read == 1699
    assert times[0] == 0.0 and np.all(np.diff(times) > 0)
    assert times[-1] - times[-2] == pytest.approx(1 / 60, rel=0.01)


@pytest.mark.skipif(not RESIDENTIAL.exists(), reason="real clip not available")
def test_decoder_child_keeps_stderr_clean(capfd):
    """The H.264 clip makes FFmpeg log a macroblock error; nothing may reach stderr."""
    with VideoReader(RESIDENTIAL, max_frames=30) as reader:
        assert sum(1 for _ in reader) == 30
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("kind, message", [
    ("missing", "no such file"),
    ("directory", "is a directory"),
    ("empty", "empty file"),
    ("text", "not a readable video"),
    ("random", "not a readable video"),
    ("no_frames", "(no frames|not a readable video)"),
])
def test_bad_inputs_raise_input_error_naming_the_file(tmp_path, kind, message):
    path = tmp_path / f"{kind}.avi"
    if kind == "directory":
        path.mkdir()
    elif kind == "empty":
        path.touch()
    elif kind == "text":
        path.write_text("frame,id\n1,2\n")
    elif kind == "random":
        path.write_bytes(np.random.default_rng(0).integers(0, 256, 50_000, np.uint8).tobytes())
    elif kind == "no_frames":
        cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), FPS, (W, H)).release()
    with pytest.raises(InputError, match=message) as err:
        VideoReader(path)
    assert str(path) in str(err.value)
    if kind not in ("missing", "directory"):
        with pytest.raises(InputError, match=str(path)):
            probe(path)


def test_truncated_file_is_a_clean_partial_read(clip, tmp_path):
    data = clip.read_bytes()
    path = tmp_path / "truncated.avi"
    path.write_bytes(data[: len(data) // 2])
    with VideoReader(path) as reader:
        frames = list(reader)
    assert 1 <= len(frames) < N_FRAMES
    assert [f.index for f in frames] == list(range(1, len(frames) + 1))


def test_decoder_abort_mid_file_yields_frames_then_input_error(clip, monkeypatch, capfd,
                                                               tmp_path):
    """What the dying decoder prints (the hook writes a glibc-style line to its fd 2) goes
    to its log, not to this process's stderr."""
    monkeypatch.setenv(ABORT_HOOK_ENV, "5")
    got = []
    with VideoReader(clip) as reader:
        pid = reader.pid
        with pytest.raises(InputError, match="decoder aborted after 5 frames") as err:
            for frame in reader:
                got.append(frame.index)
    assert got == [1, 2, 3, 4, 5]
    assert str(clip) in str(err.value)
    assert _gone(pid)
    out, errors = capfd.readouterr()
    assert out == "" and errors == ""
    assert reader.save_decoder_log(tmp_path / "decoder.log")
    assert "malloc_consolidate()" in (tmp_path / "decoder.log").read_text()


def test_decoder_abort_before_first_frame_quotes_the_decoder(clip, monkeypatch, capfd):
    monkeypatch.setenv(ABORT_HOOK_ENV, "0")
    with pytest.raises(InputError, match="before the first frame") as err:
        VideoReader(clip)
    assert str(clip) in str(err.value)
    assert "(decoder said: malloc_consolidate(): invalid chunk size" in str(err.value)
    assert capfd.readouterr().err == ""


def test_quiet_decoder_leaves_no_log(clip, tmp_path):
    with VideoReader(clip) as reader:
        list(reader)
    assert not reader.save_decoder_log(tmp_path / "decoder.log")
    assert not (tmp_path / "decoder.log").exists()


def test_no_child_left_after_close_exception_or_early_stop(clip):
    with VideoReader(clip) as reader:  # read to the end
        list(reader)
    assert _gone(reader.pid)
    reader = VideoReader(clip)  # child still decoding, blocked on a full ring
    next(iter(reader))
    reader.close()
    reader.close()
    assert _gone(reader.pid)
    with pytest.raises(RuntimeError):  # an error in the caller's loop
        with VideoReader(clip) as reader:
            for _ in reader:
                raise RuntimeError("caller failed")
    assert _gone(reader.pid)


def test_probe_reads_container_info(clip):
    info = probe(clip)
    assert (info.width, info.height, info.frame_count) == (W, H, N_FRAMES)
    assert math.isclose(info.fps, FPS)
