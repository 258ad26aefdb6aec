"""The background estimate from the tracking's own read (app/readonce.py): one decoder, the
same outputs as a second read of the video's start, and a source that fails while it reads
ahead."""

import json

import numpy as np
import pytest

from vtrack.app import config, profile, readonce
from vtrack.app.track import TrackOptions, track_video
from vtrack.errors import InputError
from vtrack.io.video import Frame

OUTPUTS = ("tracks.csv", "crossings.csv", "vehicles.csv", "counts.csv")


def test_sample_numbers():
    # 6 s at 25 fps: 150 frames, every 6th from frame 1
    assert readonce.sample_numbers(25.0, 1000, None, 6.0, 25) == set(range(1, 150, 6))
    # a clip of 80 frames: stride 3.2
    assert sorted(readonce.sample_numbers(25.0, 80, None, 6.0, 25))[-3:] == [71, 74, 77]
    assert readonce.sample_numbers(25.0, 1000, 40, 6.0, 25) == {1 + int(k * 1.6)
                                                                for k in range(25)}
    assert readonce.sample_numbers(25.0, 20, None, 6.0, 25) == set()   # fewer than samples
    assert readonce.sample_numbers(25.0, 1000, None, 0.0, 25) == set()  # estimate off


def _decoders(monkeypatch) -> list[object]:
    """The VideoReaders a run opens, recorded."""
    import vtrack.io.video as video

    opened: list[object] = []

    class Counted(video.VideoReader):
        def __init__(self, *args, **kwargs):
            opened.append(kwargs.get("keep"))
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(video, "VideoReader", Counted)
    return opened


@pytest.mark.parametrize("profiled", [False, True])
def test_one_decoding_and_the_outputs_of_a_second_read(synth_video, tmp_path, monkeypatch,
                                                       profiled):
    video = synth_video(0, frames=120) / "video.avi"
    cfg = config.load(None)
    opts = TrackOptions(profile=profiled)
    opened = _decoders(monkeypatch)
    track_video(video, tmp_path / "hybrid", cfg, opts)
    # the default hybrid detector's appearance model needs the full frames that reading
    # ahead drops: it reads the start a second time
    assert len(opened) == 2 and opened[1] is not None
    cfg.detector.kind = "mog2"               # MOG2 alone reads the video once
    opened.clear()
    track_video(video, tmp_path / "once", cfg, opts)
    assert opened == [None]                  # the tracking's read alone
    monkeypatch.setattr(readonce, "LOOKAHEAD_BYTES", 0)   # too little memory: a second read
    opened.clear()
    track_video(video, tmp_path / "twice", cfg, opts)
    assert len(opened) == 2 and opened[1] is not None
    for name in OUTPUTS:
        once, twice = ((tmp_path / d / name) for d in ("once", "twice"))
        assert once.exists() and once.read_bytes() == twice.read_bytes(), name
    assert (tmp_path / "once" / "tracks.csv").read_text().count("\n") > 100
    if profiled:   # both ways, the stages and the remainder add up to the wall time
        for run in ("once", "twice"):
            prof = json.loads((tmp_path / run / "profile.json").read_text())
            rows = {r["stage"]: r["seconds"] for r in prof["stages"]}
            assert rows[profile.BACKGROUND] > 0 and rows[profile.START] > 0, rows
            assert rows[profile.UNACCOUNTED] >= 0, rows
            assert sum(rows.values()) == pytest.approx(prof["wall_seconds"], abs=1e-3)


class _Detector:
    """Records what `read_once` hands it."""

    def __init__(self) -> None:
        self.samples: list[int] | None = None

    def prepare(self, image: np.ndarray) -> np.ndarray:
        return image // 2

    def initialise(self, images, prepared=False):
        assert prepared
        self.samples = [int(image[0, 0, 0]) for image in images]


def _source(n: int, fail_after: int | None = None):
    for k in range(1, n + 1):
        yield Frame(k, k / 25.0, np.full((2, 2, 3), 2 * k, np.uint8))
        if k == fail_after:
            raise InputError(f"lost after frame {k}")


def _no_timing():
    import contextlib

    return contextlib.nullcontext()


def test_read_once_hands_on_every_frame_after_the_estimate():
    det = _Detector()
    out = []
    for frame, prepared in readonce.read_once(_source(10), det, {1, 4, 7}, _no_timing):
        assert det.samples == [1, 4, 7]       # estimated before the first frame
        out.append((frame.index, prepared, int(frame.image[0, 0, 0])))
    # frames 1-7 read ahead and prepared, the rest as decoded
    assert out == [(k, True, k) for k in range(1, 8)] + [(k, False, 2 * k) for k in (8, 9, 10)]


def test_read_once_with_a_source_that_fails_while_reading_ahead():
    det = _Detector()
    got = []
    with pytest.raises(InputError, match="after frame 5"):
        for frame, prepared in readonce.read_once(_source(10, fail_after=5), det, {1, 4, 7},
                                                  _no_timing):
            got.append(frame.index)
    assert det.samples == [1, 4] and got == [1, 2, 3, 4, 5]


def test_fits():
    assert readonce.fits({1, 150}, (640, 360))
    assert not readonce.fits({1, 2000}, (640, 360))
    assert readonce.fits(set(), (640, 360))
