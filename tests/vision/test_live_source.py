"""Live sources: a local MJPEG camera over HTTP started by each test (see conftest
MjpegCamera); SOURCE parsing; LiveClock."""

from __future__ import annotations

import math
import time

import cv2
import numpy as np
import pytest

from vtrack.errors import InputError
from vtrack.io.sources import parse_source
from vtrack.io.video import LiveClock, VideoReader

W, H, BITS = 128, 64, 16  # stamped frames: BITS black/white 16x16 squares = the frame number


def _stamped(n: int) -> bytes:
    image = np.full((H, W, 3), 90, np.uint8)
    for b in range(BITS):
        y, x = divmod(b, W // 16)
        image[16 * y:16 * y + 16, 16 * x:16 * x + 16] = 255 * (n >> b & 1)
    return cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()


def _stamp(image: np.ndarray) -> int:
    n = 0
    for b in range(BITS):
        y, x = divmod(b, W // 16)
        if image[16 * y + 4:16 * y + 12, 16 * x + 4:16 * x + 12].mean() > 128:
            n |= 1 << b
    return n


@pytest.fixture(scope="module")
def stamped():
    return [_stamped(n) for n in range(4096)]


@pytest.mark.parametrize("text, kind, target, stem", [
    ("rtsp://user:pw@10.0.0.7:554/Streaming/Channels/101", "stream",
     "rtsp://user:pw@10.0.0.7:554/Streaming/Channels/101", "10.0.0.7_554_Streaming_Channels_101"),
    ("HTTP://cam.local/video.mjpg?x=1", "stream", "HTTP://cam.local/video.mjpg?x=1",
     "cam.local_video.mjpg"),
    ("https://example.org/live/", "stream", "https://example.org/live/", "example.org_live"),
    ("cam:0", "camera", 0, "cam0"),
    ("cam:12", "camera", 12, "cam12"),
    ("videos/clip.mp4", "file", "videos/clip.mp4", "clip"),
    ("rtsp:/host/cam", "file", "rtsp:/host/cam", "cam"),   # not an address: a path
])
def test_source_spec_is_kept_verbatim(text, kind, target, stem):
    src = parse_source(text)
    assert (src.spec, src.kind, src.target, src.stem) == (text, kind, target, stem)
    assert src.is_file == (kind == "file")


def test_malformed_camera_index_is_an_input_error():
    with pytest.raises(InputError, match="cam:front"):
        parse_source("cam:front")


def test_live_clock_follows_stream_then_wall_clock_and_stays_monotone():
    clock = LiveClock(25.0)
    # stream timestamps that keep pace with the wall clock: used as they are (smooth)
    times = [clock(40.0 * k, 100.0 + 0.04 * k + 0.01 * (k % 2), 0) for k in range(50)]
    assert np.diff(times) == pytest.approx(np.full(49, 0.04))
    # a stream whose frame numbers FFmpeg times at 25 fps but that sends 10 fps: the wall
    # clock takes over once they drift MAX_CLOCK_DRIFT_S apart
    clock = LiveClock(25.0)
    times = [clock(40.0 * k, 0.1 * k, 0) for k in range(100)]
    steps = np.diff(times)
    assert steps[:20] == pytest.approx(0.04) and steps[-50:] == pytest.approx(0.1)
    assert np.all(steps > 0)
    # a reconnection (timestamps restart at 0): the gap is the wall-clock outage
    clock = LiveClock(25.0)
    a = [clock(40.0 * k, 0.04 * k, 0) for k in range(10)]
    b = [clock(40.0 * k, 3.0 + 0.04 * k, 1) for k in range(10)]
    assert b[0] - a[-1] == pytest.approx(3.0 - 0.36)
    assert np.diff(b) == pytest.approx(np.full(9, 0.04))
    # no timestamps at all (NaN): wall clock, never a step under 0.2 T
    clock = LiveClock(25.0)
    times = [clock(math.nan, t, 0) for t in (0.0, 0.04, 0.04, 0.05, 0.2)]
    assert np.all(np.diff(times) >= 0.2 * 0.04 - 1e-12)
    assert times[-1] == pytest.approx(0.2)


def test_slow_consumer_drops_frames_and_latency_stays_bounded(mjpeg_camera, stamped):
    """The camera sends 100 fps; the consumer takes 30 ms a frame. Frames must be dropped
    and the frame in hand must stay recent (a growing queue would lag ~70 frames more
    every second)."""
    fps = 100.0
    camera = mjpeg_camera(stamped, fps=fps)
    lags = []
    with VideoReader(camera.url, reconnect_seconds=5) as reader:
        assert reader.info.live and (reader.info.width, reader.info.height) == (W, H)
        for frame in reader:
            lags.append((time.monotonic() - camera.start) * fps - _stamp(frame.image))
            time.sleep(0.03)
            if frame.index == 100:
                break
        dropped = reader.dropped_frames
    stamps_lag = np.array(lags)
    print(f"dropped {dropped} of {camera.sent} sent; lag (frames) median "
          f"{np.median(stamps_lag[50:]):.1f}, max {stamps_lag[50:].max():.1f}")
    assert dropped > 0
    # Waiting in the ring (LIVE_SLOTS), held, or being decoded: ~3 frames at 100 fps each
    # (30 ms at the consumer), plus scheduling delays on a busy machine (the maximum can
    # spike when the machine is loaded); a queue that grew would lag ~70 frames more every
    # second, ~100 to 200 frames over the second half.
    assert np.median(stamps_lag[50:]) <= 20


def test_dropped_connection_reconnects_and_times_stay_monotone(mjpeg_camera, stamped):
    camera = mjpeg_camera(stamped, fps=50.0, cut_after=20, down_for=1.0)
    frames = []
    with VideoReader(camera.url, max_frames=60, reconnect_seconds=10) as reader:
        for frame in reader:
            frames.append((frame.index, frame.time, _stamp(frame.image), reader.reconnects))
    assert reader.reconnects == 1 and camera.connections == 2
    assert len(frames) == 60
    times = np.array([f[1] for f in frames])
    assert np.all(np.diff(times) > 0)
    after = [k for k, f in enumerate(frames) if f[3] == 1]
    gap = times[after[0]] - times[after[0] - 1]
    assert gap >= 0.9                           # the outage (1 s) shows in the timeline
    # a camera keeps filming: the frames after the reconnection are a second or more later
    assert frames[after[0]][2] - frames[after[0] - 1][2] >= 0.9 * 50


def test_source_that_never_comes_back_raises_after_the_frames_read(mjpeg_camera, stamped):
    camera = mjpeg_camera(stamped, fps=50.0, cut_after=10, down_for=None)
    got = 0
    t0 = time.monotonic()
    with pytest.raises(InputError, match="source lost: no reconnection within 1 s") as err:
        with VideoReader(camera.url, reconnect_seconds=1) as reader:
            for _ in reader:
                got += 1
    assert 1 <= got <= 10 and camera.url in str(err.value)
    assert time.monotonic() - t0 < 1 + 10   # gave up after about reconnect_seconds


@pytest.mark.parametrize("source, message", [
    ("rtsp://127.0.0.1:9/x", "cannot open the stream"),
    ("http://127.0.0.1:9/cam.mjpg", "cannot open the stream"),
    ("cam:99", "cannot open camera 99"),
])
def test_unreachable_live_source_is_an_input_error_quoting_the_decoder(source, message):
    t0 = time.monotonic()
    with pytest.raises(InputError) as err:
        VideoReader(source, reconnect_seconds=0.5)
    text = str(err.value)
    assert text.startswith(f"{source}: {message} (tried for 0.5 s)")
    assert "\n" not in text
    if source.startswith(("rtsp", "http")):
        assert "Connection refused" in text    # FFmpeg's own message, from the log
    assert time.monotonic() - t0 < 10


def test_video_file_served_over_http_ends_for_good(tmp_path):
    """A source of known length (here an AVI file behind a plain HTTP server) is over once
    all of it was read: no reconnection (which would start it again from the beginning)."""
    import functools
    import http.server
    import threading

    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (W, H))
    for n in range(40):
        writer.write(cv2.imdecode(np.frombuffer(_stamped(n), np.uint8), cv2.IMREAD_COLOR))
    writer.release()
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=tmp_path)
    handler.log_message = lambda *a: None
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/clip.avi"
        with VideoReader(url, reconnect_seconds=30) as reader:
            stamps = [_stamp(f.image) for f in reader]
            time.sleep(0.05)
    finally:
        server.shutdown()
        server.server_close()
    assert reader.reconnects == 0
    assert stamps[-1] == 39 and stamps == sorted(stamps)
    assert len(stamps) + reader.dropped_frames == 40
