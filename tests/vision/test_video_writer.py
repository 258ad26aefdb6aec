"""The annotated video: H.264 / yuv420p / index first through PyAV, read back with PyAV and
our own MP4 box walk; MPEG-4 Part 2 with a warning without an H.264 encoder or PyAV."""

from __future__ import annotations

import sys
import cv2
import numpy as np
import pytest

from vtrack.io import video_writer
from vtrack.io.video_writer import OpenCVWriter, PyAVWriter, open_video_writer

av = pytest.importorskip("av")
FPS, W, H = 25.0, 96, 64


def _marked(n: int, w: int = W, h: int = H) -> np.ndarray:
    image = np.full((h, w, 3), 40, np.uint8)
    cv2.rectangle(image, (2 * n % w, 10), (2 * n % w + 12, 30), (0, 0, 255), -1)
    return image


def test_writes_browser_playable_h264(tmp_path, read_video):
    """The codec, pixel format and box order read back from the file itself."""
    assert video_writer.h264_encoder() is not None, "PyAV's wheel carries an H.264 encoder"
    out = tmp_path / "annotated.mp4"
    with open_video_writer(out, FPS, (W, H)) as writer:
        assert writer.warning is None
        for n in range(30):
            writer.write(_marked(n), n / FPS)
        assert not out.exists()          # only the temporary sibling while writing
    got = read_video(out)
    print(f"read back: {got['codec']} {got['pix_fmt']} boxes {got['boxes']}")
    assert got["codec"] == "h264" and got["pix_fmt"] == "yuv420p"
    assert got["frames"] == 30 and got["size"] == (W, H)
    assert got["boxes"].index("moov") < got["boxes"].index("mdat")      # faststart
    assert np.diff(got["times"]) == pytest.approx(np.full(29, 1 / FPS), abs=1e-4)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["annotated.mp4"]


def test_frames_keep_their_timestamps_and_odd_sizes_are_padded(tmp_path, read_video):
    """A live run that dropped frames plays in real time; yuv420p needs even sides."""
    out = tmp_path / "odd.mp4"
    times = [0.0, 0.04, 0.08, 0.5, 0.54, 1.5]
    with open_video_writer(out, 29.97, (W + 1, H + 1)) as writer:
        for n, t in enumerate(times):
            writer.write(_marked(n, W + 1, H + 1), t)
    got = read_video(out)
    assert got["size"] == (W + 2, H + 2) and got["frames"] == len(times)
    assert got["times"] == pytest.approx(times, abs=1e-4)


def test_without_h264_encoder_warns_and_writes_mpeg4_part2(tmp_path, monkeypatch, read_video):
    monkeypatch.setattr(video_writer, "H264_ENCODERS", ("no-such-encoder",))
    out = tmp_path / "annotated.mp4"
    with open_video_writer(out, FPS, (W, H)) as writer:
        for n in range(10):
            writer.write(_marked(n))
    assert "no H.264 encoder" in writer.warning and "MPEG-4 Part 2" in writer.warning
    got = read_video(out)
    assert (got["codec"], got["pix_fmt"], got["frames"]) == ("mpeg4", "yuv420p", 10)
    assert got["boxes"].index("moov") < got["boxes"].index("mdat")


def test_without_pyav_falls_back_to_opencv_mpeg4_with_a_warning(tmp_path, monkeypatch,
                                                                read_video):
    monkeypatch.setitem(sys.modules, "av", None)    # import av -> ImportError
    out = tmp_path / "annotated.mp4"
    with open_video_writer(out, FPS, (W, H)) as writer:
        assert isinstance(writer, OpenCVWriter)
        for n in range(10):
            writer.write(_marked(n))
    assert "pip install 'vtrack[video]'" in writer.warning
    monkeypatch.undo()
    got = read_video(out)
    assert (got["codec"], got["frames"]) == ("mpeg4", 10)


@pytest.mark.parametrize("make", [
    lambda out: PyAVWriter(out, FPS, (W, H), video_writer.h264_encoder()),
    lambda out: OpenCVWriter(out, FPS, (W, H)),
], ids=["pyav", "opencv"])
def test_interrupted_writer_leaves_a_finished_video_or_nothing(tmp_path, make, read_video):
    out = tmp_path / "annotated.mp4"
    with pytest.raises(KeyboardInterrupt):
        with make(out) as writer:
            for n in range(7):
                writer.write(_marked(n))
            raise KeyboardInterrupt
    assert read_video(out)["frames"] == 7
    empty = tmp_path / "empty.mp4"
    with make(empty):
        pass
    assert not empty.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["annotated.mp4"]
    with make(tmp_path / "x.mp4") as writer:
        with pytest.raises(ValueError, match="96x64"):
            writer.write(np.zeros((10, 10, 3), np.uint8))
