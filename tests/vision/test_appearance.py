"""The appearance detector (vision/appearance.py), the fusion of its boxes with MOG2's blobs
(vision/fusion.py) and the fused detector in `vtrack track` (vision/hybrid.py): the shipped
model on a real frame, its errors, the split of a merged blob, provenance and class through
to the output files."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest

from vtrack.cli import main
from vtrack.boxes import iou
from vtrack.vision.appearance import (SHIPPED_SHA256, VEHICLE_CLASSES, AppearanceBoxes,
                                      AppearanceModel, cut, decode, grid, letterbox,
                                      shipped_model, tiles, with_riders)
from vtrack.vision.fusion import APPEARANCE, BOTH, MOTION, Fused, follow, fuse, renew

ROOT = Path(__file__).resolve().parents[2]
HANOI = ROOT.parent / "shared" / "videos" / "hanoi_crossroads_queue.mp4"


def _frame(path: Path, index: int) -> np.ndarray:
    cap = cv2.VideoCapture(str(path))
    for _ in range(index):
        ok, image = cap.read()
        assert ok
    cap.release()
    return image


@pytest.fixture(scope="module")
def model() -> AppearanceModel:
    return AppearanceModel()


def _app(boxes: list[list[float]], classes: list[str], scores: list[float] | None = None
         ) -> AppearanceBoxes:
    return AppearanceBoxes(np.array(boxes, float).reshape(-1, 4),
                           np.array(scores or [0.8] * len(boxes)),
                           np.array([VEHICLE_CLASSES.index(c) for c in classes], int))


# ------------------------------------------------------------------ the model


def test_shipped_model_is_the_recorded_file():
    """The model inside the package is the file of ../shared/models/SOURCE.md, with its
    licence and notice beside it."""
    import hashlib

    path = shipped_model()
    assert hashlib.sha256(path.read_bytes()).hexdigest() == SHIPPED_SHA256
    assert (path.parent / "LICENSE.yolox_nano.txt").read_text().startswith(" ") or \
        "Apache License" in (path.parent / "LICENSE.yolox_nano.txt").read_text()
    assert "3d4f1119d0694200671c08069ecb847aa0d8495a" in (path.parent / "NOTICE.md").read_text()


def test_wheel_carries_the_model(tmp_path):
    """`pip install .` carries the model: the wheel built from the project holds it, its
    licence and its notice."""
    out = tmp_path / "wheel"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w",
                    str(out), str(ROOT)], check=True, capture_output=True, timeout=600)
    names = zipfile.ZipFile(next(out.glob("vtrack-*.whl"))).namelist()
    for f in ("yolox_nano.onnx", "LICENSE.yolox_nano.txt", "NOTICE.md"):
        assert f"vtrack/models/{f}" in names


def test_decode_follows_yoloxs_grid():
    """One raw row at a known cell decodes to the box YOLOX's head means: centre (dx + i) s,
    size exp(lw) s; score objectness x class."""
    cells, strides = grid(416)
    assert len(strides) == 52 * 52 + 26 * 26 + 13 * 13
    raw = np.zeros((len(strides), 85), np.float32)
    row = 52 * 52 + 26 * 3 + 5          # stride 16, cell i=5, j=3
    raw[row, :5] = [0.5, 0.25, np.log(4.0), np.log(2.0), 0.9]
    raw[row, 5 + 2] = 0.8               # COCO 2: car
    boxes, scores, coco = decode(raw, cells, strides, 0.3)
    assert coco.tolist() == [2]
    np.testing.assert_allclose(scores, [0.72], rtol=1e-6)
    cx, cy, w, h = (5.5 * 16), (3.25 * 16), 64.0, 32.0
    np.testing.assert_allclose(boxes[0], [cx - w / 2, cy - h / 2, w, h], rtol=1e-6)


def test_rider_is_part_of_the_motorcycle_and_pedestrians_are_dropped():
    """A person box on a motorcycle widens the motorcycle's box; a person on none is not a
    road user; the car stays a car."""
    boxes = np.array([[100, 120, 30, 40], [102, 95, 26, 50], [300, 100, 15, 40],
                      [200, 100, 60, 40]], float)
    out = with_riders(boxes, np.array([0.8, 0.7, 0.9, 0.6]), np.array([3, 0, 0, 2]))
    assert [VEHICLE_CLASSES[c] for c in out.classes] == ["motorcycle", "car"]
    np.testing.assert_allclose(out.boxes[0], [100, 95, 30, 65])


@pytest.mark.skipif(not HANOI.exists(), reason=f"real clip not available: {HANOI}")
def test_shipped_model_finds_the_standing_queue(model):
    """Frame 30 of the real crossroads, at the red light: the van (COCO calls it a bus or a
    car) at the bottom left and the queued riders are found by appearance, though none of
    them moves; no person is a road user of its own."""
    app = model.detect(_frame(HANOI, 30))
    names = [VEHICLE_CLASSES[c] for c in app.classes]
    assert names.count("motorcycle") >= 6
    centres = app.boxes[:, :2] + app.boxes[:, 2:] / 2
    van = (centres[:, 0] < 200) & (centres[:, 1] > 300) & (app.boxes[:, 2] > 100)
    assert van.any()
    assert set(names) <= set(VEHICLE_CLASSES)
    assert np.all((app.scores >= 0.3) & (app.scores <= 1))


@pytest.mark.skipif(not HANOI.exists(), reason=f"real clip not available: {HANOI}")
def test_opencv_dnn_agrees_with_onnxruntime(model):
    """The fallback engine (OpenCV DNN) gives the same boxes within float rounding."""
    image = _frame(HANOI, 30)
    a, b = model.detect(image), AppearanceModel(engine="opencv").detect(image)
    assert len(a) == len(b) and a.classes.tolist() == b.classes.tolist()
    np.testing.assert_allclose(a.boxes, b.boxes, atol=0.05)
    np.testing.assert_allclose(a.scores, b.scores, atol=1e-4)


def test_the_models_input_size_is_made_free():
    """onnxsize rewrites the shipped model's declared 1x3x416x416 input as 1x3xhxw (and
    its 3549 output rows as n) without changing the file's length; onnxruntime then runs
    a 256x416 input with YOLOX's rows for it. A truncated model is a ValueError."""
    import onnxruntime as ort

    from vtrack.vision.onnxsize import free_input_size

    data = shipped_model().read_bytes()
    free, shape = free_input_size(data)
    assert shape == (1, 3, 416, 416) and len(free) == len(data) and free != data
    session = ort.InferenceSession(free, providers=["CPUExecutionProvider"])
    assert session.get_inputs()[0].shape == [1, 3, "h", "w"]
    out = session.run(None, {"images": np.full((1, 3, 256, 416), 114, np.float32)})[0]
    assert out.shape == (1, len(grid(256, 416)[1]), 85) == (1, 2184, 85)
    with pytest.raises(ValueError):
        free_input_size(data[:1000])


def test_letterbox_pads_only_to_the_stride():
    """A 640x360 frame at 416: 416x234 of picture, padded to 416x256 with stride 32 (to
    416x416 without), at the same scale."""
    image = np.zeros((360, 640, 3), np.uint8)
    square, r = letterbox(image, 416)
    rect, r2 = letterbox(image, 416, 32)
    assert square.shape == (1, 3, 416, 416) and rect.shape == (1, 3, 256, 416) and r == r2
    np.testing.assert_array_equal(rect, square[:, :, :256])


@pytest.mark.skipif(not HANOI.exists(), reason=f"real clip not available: {HANOI}")
def test_a_rectangular_pass_finds_what_the_square_pass_finds(model):
    """The shipped model runs on rectangles (stride 32); on a real frame its boxes are the
    square pass's: as many within 10 %, each matched at IoU >= 0.7 but for a tenth (the
    model's zero padding below the picture differs from the square's grey rows)."""
    assert model.stride == 32
    image = _frame(HANOI, 30)
    rect = model.detect(image)
    model.stride = 0
    try:
        square = model.detect(image)
    finally:
        model.stride = 32
    assert abs(len(rect) - len(square)) <= 0.1 * len(square)
    matched = iou(square.boxes, rect.boxes).max(axis=1) >= 0.7
    assert matched.mean() >= 0.9


def _onnx_model(path: Path, classes: int | None) -> Path:
    """A tiny ONNX model with a 1x3x416x416 input: YOLOX's output rows with `classes`
    class scores (a constant), or (None) the input passed through (not YOLOX)."""
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    x = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 416, 416])
    if classes is None:
        y = helper.make_tensor_value_info("output", TensorProto.FLOAT, [1, 3, 416, 416])
        nodes = [helper.make_node("Identity", ["images"], ["output"])]
        inits = []
    else:
        shape = [1, 3549, 5 + classes]
        y = helper.make_tensor_value_info("output", TensorProto.FLOAT, shape)
        nodes = [helper.make_node("ReduceMean", ["images"], ["m"], keepdims=0),
                 helper.make_node("Expand", ["m", "shape"], ["output"])]
        inits = [helper.make_tensor("shape", TensorProto.INT64, [3], shape)]
    graph = helper.make_graph(nodes, "g", [x], [y], initializer=inits)
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    m.ir_version = 8
    onnx.save(m, str(path))
    return path


def _track_error(tmp_path: Path, capsys, synth_video, model_path: str) -> str:
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(f'[detector]\nkind = "hybrid"\nappearance_model = "{model_path}"\n')
    code = main(["track", str(synth_video(0) / "video.avi"), "--out", str(tmp_path / "r"),
                 "--config", str(cfg), "--quiet", "--max-frames", "5"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("error: ") and "\n" not in err and "Traceback" not in err
    return err


@pytest.mark.parametrize("case", ["missing", "corrupt", "not-yolox", "no-vehicles"])
def test_bad_model_is_one_error_line(tmp_path, capsys, synth_video, case):
    """A missing, corrupt or non-YOLOX model, or one without COCO's vehicle classes: one
    `error:` line naming the file, exit 2."""
    path = tmp_path / "model.onnx"
    if case == "corrupt":
        path.write_bytes(b"\x08\x07garbage" * 100)
    elif case == "not-yolox":
        _onnx_model(path, None)
    elif case == "no-vehicles":
        _onnx_model(path, 3)
    err = _track_error(tmp_path, capsys, synth_video, str(path))
    assert str(path) in err
    if case == "no-vehicles":
        assert "classes" in err


def test_a_yolox_format_model_of_any_class_layout_is_read(tmp_path):
    """A YOLOX-format model with COCO's 80 classes loads (its input size read from the
    model); its output of constants gives no box above the score floor."""
    m = AppearanceModel(_onnx_model(tmp_path / "m.onnx", 80), min_score=0.99)
    assert m.side == 416
    assert m.stride == 0   # its output rows are fixed: square passes only
    assert len(m.detect(np.zeros((90, 160, 3), np.uint8))) == 0


@pytest.mark.parametrize("size", [(1280, 720), (640, 480), (1920, 1080), (320, 240)])
def test_tiles_cover_the_frame_magnified(size):
    """The tiles cover every pixel of the frame, overlap, and show it at least 1.75 times
    as large to a 416 model as the whole-frame pass does."""
    w, h = size
    windows = tiles(w, h, 416)
    assert 2 <= len(windows) <= 4
    covered = np.zeros((h, w), bool)
    for x, y, tw, th in windows:
        covered[y:y + th, x:x + tw] = True
        assert x >= 0 and y >= 0 and x + tw <= w and y + th <= h
        assert min(416 / tw, 416 / th) >= 1.75 * min(416 / w, 416 / h)
    assert covered.all()


def test_a_tile_drops_the_boxes_it_cuts():
    """A box touching a tile's edge inside the frame is cut (its vehicle is whole in the
    neighbouring tile); one touching the frame's own edge is not."""
    boxes = np.array([[0, 10, 30, 20], [300, 10, 46, 20], [100, 100, 30, 20],
                      [100, 230, 30, 30]], float)
    assert cut(boxes, (0, 0, 346, 260), 640, 480, 2.0).tolist() == [False, True, False,
                                                                     True]


@pytest.mark.skipif(not HANOI.exists(), reason=f"real clip not available: {HANOI}")
def test_a_tile_finds_in_the_frames_pixels_what_the_whole_frame_finds(model):
    """The riders of the real queue seen through the left tile are found where the whole
    frame's pass finds them (the window's offset undone), at least as many of them."""
    image = _frame(HANOI, 30)
    h, w = image.shape[:2]
    whole = model.detect(image)
    window = tiles(w, h, model.side)[0]
    part = model.detect(image, window)
    assert part.window == window and part.scale > 1.7 * whole.scale
    x, y, tw, th = window
    c = whole.boxes[:, :2] + whole.boxes[:, 2:] / 2
    inner = (c[:, 0] > x + 40) & (c[:, 0] < x + tw - 40) & (c[:, 1] > y + 40) \
        & (c[:, 1] < y + th - 40) & (whole.boxes[:, 2] < tw / 3)
    assert inner.sum() >= 3 and len(part) >= inner.sum()
    from vtrack.boxes import iou
    assert np.median(iou(whole.boxes[inner], part.boxes).max(axis=1)) >= 0.6


# ------------------------------------------------------------------ fusion


def test_merged_blob_is_split_along_the_appearance_boxes():
    """One blob holding a car and a motorcycle (and a row of three riders in another) is
    replaced by their appearance boxes, marked as seen by both."""
    blobs = np.array([[100, 100, 120, 50], [300, 100, 90, 40]], float)
    app = _app([[100, 102, 70, 46], [175, 105, 30, 45],
                [300, 100, 28, 40], [330, 100, 28, 40], [361, 100, 28, 40]],
               ["car", "motorcycle", "motorcycle", "motorcycle", "motorcycle"])
    f = fuse(blobs, np.array([5000.0, 3000.0]), app)
    assert len(f.boxes) == 5 and set(f.source.tolist()) == {BOTH}
    np.testing.assert_allclose(f.boxes, app.boxes)
    assert [VEHICLE_CLASSES[c] for c in f.cls] == ["car", "motorcycle", "motorcycle",
                                                   "motorcycle", "motorcycle"]


def test_blob_the_model_does_not_see_stays_and_standing_vehicles_are_added():
    """A moving blob the model does not see stays a motion detection (score 1, no class);
    an appearance box no blob holds (a standing car) is a detection of its own; a box that
    sees only a small part of a large blob does not replace it."""
    blobs = np.array([[0, 0, 40, 30], [200, 200, 100, 100]], float)
    app = _app([[400, 50, 60, 30], [200, 200, 30, 30]], ["car", "car"], [0.9, 0.5])
    f = fuse(blobs, np.array([900.0, 7000.0]), app)
    assert f.source.tolist() == [MOTION, MOTION, APPEARANCE]
    np.testing.assert_allclose(f.boxes, [[0, 0, 40, 30], [200, 200, 100, 100],
                                         [400, 50, 60, 30]])
    assert f.score.tolist() == [1.0, 1.0, 0.9] and f.cls.tolist()[:2] == [-1, -1]


def test_a_box_alone_needs_the_higher_score():
    """A box no blob supports is a detection only at `alone_score`; the same score on a box
    that explains a blob is enough (two sources of evidence)."""
    blobs = np.array([[0, 0, 40, 30]], float)
    app = _app([[0, 0, 40, 30], [400, 50, 60, 30], [200, 50, 60, 30]], ["car"] * 3,
               [0.35, 0.35, 0.6])
    f = fuse(blobs, np.array([900.0]), app, alone_score=0.5)
    assert f.source.tolist() == [BOTH, APPEARANCE]
    assert f.score.tolist() == [0.35, 0.6]


def test_a_far_vehicle_keeps_its_blob_and_takes_the_class():
    """A box under 24 px on a side in the model's pixels (a far vehicle, placed to a few
    pixels) that explains a blob leaves the blob's geometry and gives it class and score;
    the same box large in the model's pixels replaces the blob."""
    blobs = np.array([[100, 100, 30, 20]], float)
    app = _app([[101, 99, 28, 22]], ["car"], [0.45])
    app.scale = 0.5                                   # 11 model px high: small
    f = fuse(blobs, np.array([500.0]), app)
    assert f.source.tolist() == [BOTH] and f.cls.tolist() == [VEHICLE_CLASSES.index("car")]
    np.testing.assert_allclose(f.boxes, blobs)
    assert f.areas.tolist() == [500.0] and f.score.tolist() == [0.45]
    app.scale = 2.0                                   # 44 model px high
    np.testing.assert_allclose(fuse(blobs, np.array([500.0]), app).boxes, app.boxes)


def test_pieces_of_one_vehicle_become_its_box():
    """Two pieces of a truck inside its appearance box are replaced by the one box."""
    blobs = np.array([[100, 100, 40, 40], [150, 100, 40, 40]], float)
    app = _app([[95, 95, 100, 50]], ["truck"])
    f = fuse(blobs, np.array([1500.0, 1500.0]), app)
    assert f.source.tolist() == [BOTH]
    np.testing.assert_allclose(f.boxes, app.boxes)


def test_boxes_ride_on_their_blobs_between_passes():
    """Between passes a box that explained a blob (a car without its shadow) moves and
    grows with that blob, so the tracker sees the same whole box every frame; a merged blob
    keeps its split; a standing car's box is held; a blob no box rode on stays motion."""
    blobs = np.array([[100, 100, 80, 50], [300, 100, 90, 40]], float)   # car+shadow, 2 cars
    app = _app([[100, 100, 60, 40], [300, 100, 44, 40], [346, 100, 44, 40],
                [500, 300, 50, 30]], ["car", "car", "car", "car"])
    f = fuse(blobs, np.array([3000.0, 3000.0]), app)
    assert f.source.tolist() == [BOTH, BOTH, BOTH, APPEARANCE]
    moved = np.array([[110, 104, 88, 55], [305, 100, 90, 40], [20, 20, 30, 30]], float)
    g = follow(f.riders(), moved, np.array([3500.0, 3000.0, 600.0]))
    assert g.source.tolist() == [MOTION, BOTH, BOTH, BOTH, APPEARANCE]
    np.testing.assert_allclose(g.boxes[0], [20, 20, 30, 30])          # the new blob
    np.testing.assert_allclose(g.boxes[1], [110, 104, 66, 44])        # 1.1 x, shifted
    np.testing.assert_allclose(g.boxes[2:4], [[305, 100, 44, 40], [351, 100, 44, 40]])
    np.testing.assert_allclose(g.boxes[4], [500, 300, 50, 30])        # standing: held
    assert g.cls.tolist() == [-1] + [VEHICLE_CLASSES.index("car")] * 4


def test_a_rider_leaves_a_blob_that_changes_too_much():
    """A carrier that doubles in width in one frame (another vehicle merged into the blob)
    drops its rider: the blob is a motion detection again; a standing box that a blob now
    covers (its vehicle drives off) gives way to the blob."""
    f = fuse(np.array([[100, 100, 60, 40]], float), np.array([2000.0]),
             _app([[100, 100, 60, 40], [400, 100, 60, 40]], ["car", "car"]))
    g = follow(f.riders(), np.array([[100, 100, 130, 40], [405, 100, 60, 40]], float),
               np.array([4000.0, 2000.0]))
    assert g.source.tolist() == [MOTION, MOTION]


def _pass(boxes: list[list[float]], classes: list[str], scale: float, whole: float,
          window: tuple[int, int, int, int] | None = None) -> AppearanceBoxes:
    app = _app(boxes, classes)
    app.scale, app.whole, app.window = scale, whole, window
    return app


def test_tiles_look_after_the_far_vehicles_and_the_whole_frame_after_the_near():
    """A tile's pass gives the far car (8 px high at the whole frame's scale) and not the
    near one (the whole frame's); the far car's box rides on through a whole-frame pass
    that does not see it, while that pass renews the near car, and a whole-frame pass that
    does see it takes it over; a tile renews only the far riders wholly inside it."""
    blobs = np.array([[100, 20, 24, 16], [400, 300, 120, 80]], float)
    areas = np.array([300.0, 8000.0])
    left = (0, 0, 600, 400)
    f = renew(Fused.empty(), blobs, areas,
              _pass([[100, 20, 24, 16], [400, 300, 120, 80]], ["car", "car"], 1.0, 0.5, left))
    assert f.source.tolist() == [MOTION, BOTH]
    np.testing.assert_allclose(f.boxes, [[400, 300, 120, 80], [100, 20, 24, 16]])
    g = renew(f.riders(), blobs, areas, _pass([[402, 300, 116, 80]], ["bus"], 0.5, 0.5))
    assert g.source.tolist() == [BOTH, BOTH]
    assert [VEHICLE_CLASSES[c] for c in g.cls] == ["bus", "car"]
    np.testing.assert_allclose(g.boxes, [[402, 300, 116, 80], [100, 20, 24, 16]])
    seen = renew(g.riders(), blobs, areas, _pass([[98, 18, 28, 20]], ["truck"], 0.5, 0.5))
    assert seen.source.tolist() == [MOTION, BOTH]        # the bus not seen: its blob
    assert seen.cls.tolist() == [-1, VEHICLE_CLASSES.index("truck")]
    np.testing.assert_allclose(seen.boxes[1], [100, 20, 24, 16])   # small: the blob's place
    for window in [(600, 0, 600, 400), (0, 0, 110, 400)]:   # outside; across its edge
        assert len(renew(g.riders(), blobs, areas, _pass([], [], 1.0, 0.5, window)).boxes) == 2
    h = renew(g.riders(), blobs, areas, _pass([], [], 1.0, 0.5, left))
    assert h.source.tolist() == [MOTION, BOTH]          # the far car's blob; the bus rides on
    np.testing.assert_allclose(h.boxes, [[100, 20, 24, 16], [402, 300, 116, 80]])


def test_without_riders_a_whole_frame_pass_is_the_plain_fusion():
    """renew with nothing riding and the whole frame's boxes is fuse (tiles off: the
    detector as it was)."""
    blobs = np.array([[100, 100, 120, 50], [400, 50, 30, 30]], float)
    areas = np.array([5000.0, 800.0])
    app = _app([[100, 102, 70, 46], [175, 105, 30, 45], [600, 300, 40, 30]],
               ["car", "motorcycle", "car"], [0.8, 0.6, 0.5])
    a, b = renew(Fused.empty(), blobs, areas, app, 0.4), fuse(blobs, areas, app, 0.4)
    for name in ("boxes", "areas", "source", "score", "cls"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_the_schedule_puts_the_tiles_half_way_between_whole_frame_passes():
    """At a pass every 3 frames the whole frame is seen on frames 1, 4, 7, ... and the two
    tiles in turn on 2, 5, 8, ...; without tiles only the whole frame."""
    from vtrack.vision.hybrid import FusedDetector

    class _Model:
        side = 416

    d = FusedDetector(None, _Model(), 3, threaded=False, windows=[(0, 0, 10, 10),
                                                                 (5, 0, 10, 10)])
    views = {n: d.view(n) for n in range(1, 12) if d.scheduled(n)}
    assert views == {1: None, 2: (0, 0, 10, 10), 4: None, 5: (5, 0, 10, 10), 7: None,
                     8: (0, 0, 10, 10), 10: None, 11: (5, 0, 10, 10)}
    plain = FusedDetector(None, _Model(), 3, threaded=False)
    assert [n for n in range(1, 12) if plain.scheduled(n)] == [1, 4, 7, 10]
    assert plain.view(4) is None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread niceness is Linux's")
def test_the_appearance_worker_yields_the_cores_to_the_pipeline():
    """The passes run in a worker thread WORKER_NICENESS nicer than the caller (the tracking
    and the image stages go first); the caller's own priority is left as it was."""
    import os
    import threading

    from vtrack.vision.hybrid import WORKER_NICENESS, FusedDetector

    class _Model:
        side = 416

    def nice() -> int:
        return os.getpriority(os.PRIO_PROCESS, threading.get_native_id())

    before = nice()
    d = FusedDetector(None, _Model(), 3)
    try:
        assert d._pool.submit(nice).result() == min(19, before + WORKER_NICENESS)
    finally:
        d.close()
    assert nice() == before


# ------------------------------------------------------------------ through the run


@pytest.mark.skipif(not HANOI.exists(), reason=f"real clip not available: {HANOI}")
def test_hybrid_run_tracks_the_standing_queue_with_classes(tmp_path):
    """`kind = "hybrid"` on the real crossroads' red light (frames 1-40, the queue stands):
    the standing road users are confirmed tracks (the van among them), vehicles.csv names
    their classes without a calibration, counts.csv counts per class (adding up to
    summary.json's counts), and detections.csv carries the appearance scores."""
    cfg = tmp_path / "cfg.toml"
    cfg.write_text('[detector]\nkind = "hybrid"\n')
    out = tmp_path / "run"
    assert main(["track", str(HANOI), "--out", str(out), "--config", str(cfg), "--quiet",
                 "--max-frames", "40", "--save-detections", "--count-line",
                 "0%,55%,100%,55%"]) == 0
    rows = list(csv.DictReader(open(out / "vehicles.csv")))
    classes = [r["class"] for r in rows]
    assert set(classes) <= {"", *VEHICLE_CLASSES}
    assert classes.count("motorcycle") >= 5
    tracks = np.loadtxt(out / "tracks.csv", delimiter=",", ndmin=2)
    centres = tracks[:, 2:4] + tracks[:, 4:6] / 2
    van = (centres[:, 0] < 200) & (centres[:, 1] > 300) & (tracks[:, 4] > 100)
    held = {int(f) for f in tracks[van, 0]}
    # the van pulls up at frame ~18 and stands from frame ~25 on
    assert len(held & set(range(20, 40))) >= 19, "the standing van is tracked frames 20-39"
    assert len(set(tracks[van, 1])) <= 2, "and keeps its identity"
    counts = list(csv.DictReader(open(out / "counts.csv")))
    summary = json.loads((out / "summary.json").read_text())
    assert {r["class"] for r in counts} >= set(VEHICLE_CLASSES)
    assert {r["class"] for r in counts} <= {*VEHICLE_CLASSES, "unknown"}
    for d in ("forward", "backward"):
        total = sum(int(r["count"]) for r in counts if r["direction"] == d)
        assert total == summary["counts"][0][d]
    assert summary["config"]["detector"]["kind"] == "hybrid"
    conf = np.loadtxt(out / "detections.csv", delimiter=",", ndmin=2)[:, 6]
    assert np.any(conf < 1) and np.all((conf >= 0.3) & (conf <= 1))


@pytest.mark.skipif(not HANOI.exists(), reason=f"real clip not available: {HANOI}")
def test_appearance_boxes_only_inside_the_region_of_interest():
    """The user's region of interest holds for the appearance model's boxes too: with the
    right half of the crossroads as the ROI, no detection lies in the left half (the van)."""
    from vtrack.vision.detect import DetectorConfig
    from vtrack.vision.hybrid import make_detector

    roi = np.array([[320, 0], [640, 0], [640, 480], [320, 480]], float)
    cfg = DetectorConfig(kind="hybrid", init_background_seconds=0.0)
    detector = make_detector(cfg, 640, 480, 6.0, roi, threaded=False)
    dets = detector.detect(_frame(HANOI, 30))
    whole = make_detector(cfg, 640, 480, 6.0, None, threaded=False).detect(_frame(HANOI, 30))
    assert len(dets) and np.all(dets.centers[:, 0] >= 320)
    assert np.any(whole.centers[:, 0] < 320)
