"""The detector's stages, each checked against the detector without it: camera motion
compensation, the background estimated from the video, blobs split among predicted boxes,
and shadows dropped while dark vehicles are kept."""

from __future__ import annotations

import cv2
import numpy as np

from test_motion_detector import RECTS, START, Scene, _match
from vtrack.vision.background import estimate_background, median_image, mode_image
from vtrack.vision.detect import DetectorConfig, MotionDetector
from vtrack.vision.stabilise import (IDENTITY, Stabiliser, border_edges_kept, corner_shift, invert,
                                     transform_boxes)


def _shaken(scene: Scene, n: int, rng: np.random.Generator) -> tuple[np.ndarray, tuple]:
    """Frame n of the scene seen by a camera that sways (a random walk plus vibration of a
    few pixels): the image shifted by (dx, dy)."""
    dx, dy = 3.0 * np.sin(0.7 * n) + rng.normal(0, 0.5), 2.0 * np.cos(0.5 * n)
    M = np.float32([[1, 0, dx], [0, 1, dy]])
    img = cv2.warpAffine(scene.frame(n), M, (scene.background.shape[1],
                                             scene.background.shape[0]),
                         borderMode=cv2.BORDER_REPLICATE)
    return img, (dx, dy)


def test_stabilised_detector_sees_a_swaying_scene_as_still():
    """Without compensation every edge of the textured background lights up as the camera
    sways; with it, the three moving rectangles are found (in the shaken frame's pixels)
    and nothing else."""
    for stabilise in (True, False):
        scene, rng = Scene(320, 240, RECTS, seed=3), np.random.default_rng(0)
        det = MotionDetector(DetectorConfig(warmup_frames=10, stabilise=stabilise), 320, 240)
        extra = []
        for n in range(START + 30):
            img, (dx, dy) = _shaken(scene, n, rng)
            d = det.detect(img)
            if n >= START + 5:
                truth = [(x + dx, y + dy, w, h) for x, y, w, h in scene.boxes(n)]
                extra.append(len(d) - 3)
                if stabilise:
                    assert len(d) == 3 and _match(d, truth).max() <= 3.0, n
        if not stabilise:
            assert np.mean(extra) != 0 or np.count_nonzero(det.foreground) > 0.05 * 320 * 240


def test_background_from_the_video_detects_vehicles_in_the_first_frame():
    """Two cars are in view from the first frame. Learning the background from the first
    frames takes them for background (their ghosts stay, static, and they are missed for a
    while); the median of frames sampled across the first seconds shows the empty road, so
    they are found from the first frame."""
    scene = Scene(320, 240, RECTS[:2], seed=4)
    frames = [scene.frame(START + n) for n in range(60)]
    det = MotionDetector(DetectorConfig(), 320, 240)
    det.initialise(frames[::3])
    found = [len(det.detect(f)) for f in frames[:10]]
    assert found[0] == 2 and min(found) == 2
    cold = MotionDetector(DetectorConfig(), 320, 240)
    assert sum(len(cold.detect(f)) for f in frames[:10]) == 0   # warm-up: nothing yet


def test_median_image_is_numpys_rounded_down():
    """The background's median of uint8 samples is np.median's rounded down, for odd and
    even counts."""
    rng = np.random.default_rng(1)
    for n in (3, 4, 25):
        images = list(rng.integers(0, 256, (n, 24, 32, 3), dtype=np.uint8))
        expected = np.median(np.stack(images), axis=0).astype(np.uint8)
        assert np.array_equal(median_image(images), expected), n


def _road() -> np.ndarray:
    """A 320 x 240 road texture (uint8 BGR, smooth random grey-brown)."""
    coarse = np.random.default_rng(6).normal(120, 20, (31, 41, 3)).astype(np.float32)
    return np.clip(cv2.resize(coarse, (320, 240), interpolation=cv2.INTER_CUBIC),
                   0, 255).astype(np.uint8)


def _platoon(n: int) -> tuple[np.ndarray, list[float]]:
    """Frame n of a lane (rows 100-124 of a 320 x 240 textured road, `_road`) filled with a
    platoon of 40 px vehicles of random colours, 4-30 px apart, driving right
    at 4 px per frame: the road shows in about a third of the lane's pixels; and the centres
    of the vehicles wholly in view."""
    rng = np.random.default_rng(5)
    colours = rng.integers(20, 236, (40, 3))
    starts = np.cumsum(40 + rng.integers(4, 30, 40))
    img = _road().astype(np.float32)
    centres = []
    for colour, start in zip(colours, starts):
        x = 340 - int(start) + 4 * n
        if -40 < x < 320:
            img[100:124, max(x, 0):min(x + 40, 320)] = colour
            if 0 <= x <= 280:
                centres.append(x + 20.0)
    centres.sort()
    img += np.random.default_rng(n).normal(0, 2, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8), centres


def test_background_under_a_dense_platoon_is_the_road():
    """Vehicles cover the lane in two thirds of the samples, each time in another colour:
    their median is a blend of vehicles (detections in the first frame merge neighbours or
    fall between them), while the most frequent colour (the mode, used where few samples
    are near the median) is the road, and each vehicle is found on its own from the first
    frame."""
    samples = [_platoon(n)[0] for n in range(0, 150, 6)]
    road = _road()
    lane = (slice(100, 124), slice(None))
    blend = np.abs(median_image(samples)[lane].astype(int) - road[lane]).max(axis=2)
    mode = np.abs(estimate_background(samples, 12, 0.5)[lane].astype(int) - road[lane]).max(axis=2)
    assert np.mean(blend > 12) > 0.2 and np.mean(mode > 12) < 0.02
    for support, whole in ((0.5, True), (0.0, False)):
        det = MotionDetector(DetectorConfig(init_background_support=support), 320, 240)
        det.initialise(samples)
        ok = []
        for n in range(6):
            img, centres = _platoon(n)
            d = det.detect(img)
            lane_dets = np.sort(d.centers[(d.centers[:, 1] > 100) & (d.centers[:, 1] < 124), 0])
            inside = lane_dets[(lane_dets >= 20) & (lane_dets <= 300)]
            ok.append(len(inside) == len(centres)
                      and np.abs(inside - np.array(centres)).max() <= 2.0)
        assert all(ok) == whole, (support, ok)


def test_mode_image_is_the_centre_of_the_largest_group():
    """Against a direct count per pixel: the sample with the most samples within the
    tolerance in every channel (the first of equals), and the rounded mean of its group."""
    rng = np.random.default_rng(2)
    images = list(rng.integers(0, 256, (9, 6, 7, 3), dtype=np.uint8) // 16 * 16)
    got = mode_image(images, 20)
    S = np.stack(images).astype(int)
    for y in range(6):
        for x in range(7):
            p = S[:, y, x]
            near = np.abs(p[:, None] - p[None, :]).max(axis=2) <= 20
            centre = int(np.argmax(near.sum(axis=1)))
            expected = np.floor(p[near[centre]].mean(axis=0) + 0.5)
            assert np.array_equal(got[y, x], expected), (y, x)


def test_a_well_supported_median_is_kept():
    """Where most samples are near the median (a road that vehicles cross now and then),
    the estimate is the median itself."""
    rng = np.random.default_rng(3)
    road = rng.integers(60, 200, (20, 30, 3), dtype=np.uint8)
    images = []
    for k in range(25):
        img = np.clip(road + rng.normal(0, 2, road.shape), 0, 255).astype(np.uint8)
        if k % 4 == 0:
            img[5:12, 3 + k % 20:10 + k % 20] = rng.integers(0, 256, 3)
        images.append(img)
    assert np.array_equal(estimate_background(images, 12, 0.5), median_image(images))


def test_blob_holding_two_predicted_vehicles_is_split():
    """Two cars side by side touch in the mask (one blob). Given their predicted boxes, the
    detector returns one detection per car; without them, one merged blob."""
    bg = np.full((240, 320, 3), 110, np.uint8)
    mog_frames = [bg.copy() for _ in range(20)]
    img = bg.copy()
    img[100:120, 60:120] = (40, 40, 200)     # car A 60 x 20
    img[120:140, 70:130] = (200, 60, 40)     # car B right below, touching
    predicted = np.array([[60, 100, 60, 20], [70, 120, 60, 20]], float)
    for priors, expect in ((predicted, 2), (None, 1)):
        det = MotionDetector(DetectorConfig(warmup_frames=5, min_motion=0.0), 320, 240)
        for f in mog_frames:
            det.detect(f)
        d = det.detect(img, priors)
        assert len(d) == expect
        if expect == 2:
            got = d.boxes[np.argsort(d.boxes[:, 1])]
            assert np.allclose(got, predicted, atol=6)   # blur and closing add ~3 px


def test_shadow_dropped_dark_vehicle_kept():
    """A car's cast shadow (the road darkened by one factor: its texture shows through) is
    dropped; a dark grey car of the road's colour family (which MOG2 also labels shadow,
    but which is smooth paint over a textured road) is kept."""
    rng = np.random.default_rng(5)
    grey = cv2.resize(rng.normal(110, 25, (31, 41)).astype(np.float32), (320, 240),
                      interpolation=cv2.INTER_CUBIC)
    grey += rng.normal(0, 25, grey.shape).astype(np.float32)   # coarse asphalt grain
    texture = np.repeat(grey[:, :, None], 3, axis=2)   # grey asphalt: chroma as a shadow's
    def frame(n):
        img = texture.copy()
        if n >= 30:
            img[60:100, 40:140] *= 0.6                # a cast shadow, 100 x 40
            img[150:180, 180:250] = (70, 70, 70)      # a dark grey car, 70 x 30
        img += rng.normal(0, 2.0, img.shape).astype(np.float32)
        return np.clip(img, 0, 255).astype(np.uint8)
    det = MotionDetector(DetectorConfig(warmup_frames=10, min_motion=0.0), 320, 240)
    for n in range(32):
        d = det.detect(frame(n))
    centres = d.centers
    assert np.any(np.all(np.abs(centres - (215, 165)) < 6, axis=1)), centres   # the car
    assert not np.any(np.all(np.abs(centres - (90, 80)) < 20, axis=1)), centres  # no shadow
    plain = MotionDetector(DetectorConfig(warmup_frames=10, min_motion=0.0,
                                          shadow_texture=0.0), 320, 240)
    for n in range(32):
        d0 = plain.detect(frame(n))
    assert not np.any(np.all(np.abs(d0.centers - (215, 165)) < 6, axis=1))   # car lost


def test_outlined_car_of_the_road_colour_kept(monkeypatch):
    """A car painted the road's colour shows only its dark outline, which MOG2 labels shadow
    (a darker copy of the road) and which is too thin for the per-window texture test: the
    long thin dark lines are kept, the car found; a cast shadow (wide) and a far vehicle's
    short shadow strip are still dropped. Without the line test the car is lost."""
    from vtrack.vision import shadows

    rng = np.random.default_rng(7)
    grey = cv2.resize(rng.normal(110, 6, (31, 41)).astype(np.float32), (320, 240),
                      interpolation=cv2.INTER_CUBIC)
    road = np.repeat(grey[:, :, None], 3, axis=2)

    def frame(n):
        img = road.copy()
        if n >= 30:
            img[60:100, 40:140] *= 0.6                 # a cast shadow, 100 x 40
            img[30:33, 250:258] *= 0.6                 # a far vehicle's shadow strip, 8 x 3
            x0, y0, x1, y1 = 180, 150, 240, 174        # the car, 60 x 24: only its outline
            img[y0:y1, x0:x1] *= 0.6
            img[y0 + 2:y1 - 2, x0 + 2:x1 - 2] = road[y0 + 2:y1 - 2, x0 + 2:x1 - 2]
            img[y0 + 2:y1 - 2, x0 + 14:x0 + 16] *= 0.6     # the windscreen's edge
        img += rng.normal(0, 2.0, img.shape).astype(np.float32)
        return np.clip(img, 0, 255).astype(np.uint8)

    def centres():
        det = MotionDetector(DetectorConfig(warmup_frames=10, min_motion=0.0), 320, 240)
        for n in range(32):
            d = det.detect(frame(n))
        return d.centers

    found = centres()
    assert np.any(np.all(np.abs(found - (210, 162)) < 6, axis=1)), found      # the car
    assert not np.any(np.all(np.abs(found - (90, 80)) < 20, axis=1)), found   # no shadow
    assert not np.any(np.all(np.abs(found - (254, 31)) < 8, axis=1)), found   # no strip
    monkeypatch.setattr(shadows, "LINE_GREY", np.inf)
    lost = centres()
    assert not np.any(np.all(np.abs(lost - (210, 162)) < 6, axis=1)), lost


def _kerb_scene(frames: int, sway: float, parallax: float, seed: int = 0):
    """A textured road with a white kerb across the picture and a car crossing it, seen by
    a camera that sways by up to `sway` px; the kerb stands above the road, so in every
    other frame it moves `parallax` px further than the road (a similarity transform, which
    the stabiliser fits, cannot follow both). Yields (frame, the car's true box)."""
    texture = np.random.default_rng(9).normal(0, 12, (30, 40, 3)).astype(np.float32)
    road = np.float32(70) + cv2.resize(texture, (320, 240))
    kerb = np.zeros((240, 320), np.float32)
    kerb[100:104] = 1.0
    rng = np.random.default_rng(seed)
    for n in range(frames):
        lift = np.float32([[1, 0, 0], [0, 1, parallax if n % 2 else 0.0]])
        k = cv2.warpAffine(kerb, lift, (320, 240))[:, :, None]
        img, x = road * (1 - k) + 225 * k, -40 + 6 * n
        if 0 <= x < 320:
            img[90:114, x:x + 40] = (40, 40, 200)
        dx, dy = sway * np.sin(0.9 * n), sway * np.cos(0.6 * n)
        img = cv2.warpAffine(img, np.float32([[1, 0, dx], [0, 1, dy]]), (320, 240),
                             borderMode=cv2.BORDER_REPLICATE)
        img += rng.normal(0, 2.0, img.shape).astype(np.float32)
        yield np.clip(img, 0, 255).astype(np.uint8), (x + dx, 90 + dy, 40, 24)


def test_an_edge_the_stabiliser_leaves_shifted_is_not_foreground():
    """A camera sways by 2.5 px and the stabiliser warps each frame back, but the kerb, in
    parallax, stays 0.7 px off in every other frame: a third of its contrast, so MOG2 alone
    lights the whole kerb up, and the car on it is lost in a picture-wide blob in each of
    those frames. Compared with the background's range over the pixels near each one
    (jitter.py, the default tolerance) the kerb stays background and the car is found, on
    its own, in every frame."""
    found = {}
    for tolerance in (DetectorConfig().shift_tolerance, 0.0):
        det = MotionDetector(DetectorConfig(shift_tolerance=tolerance), 320, 240)
        det.initialise([f for f, _ in _kerb_scene(3, 0.0, 0.0, seed=1)])
        widths = []
        for img, (x, y, w, h) in _kerb_scene(60, 2.5, 0.7):
            d = det.detect(img)
            if 0 < x < 280:
                widths.append(d.boxes[:, 2])
        assert det.stabiliser.moved
        found[tolerance > 0] = widths
    assert len(found[True]) == 47
    assert all(len(w) == 1 and 40 <= w[0] < 50 for w in found[True])
    assert sum(len(w) == 0 for w in found[False]) >= 20     # the 24 shifted frames


def _van_scene(frames: int):
    """A textured road seen by a swaying camera while a checkered van, 300 x 230 px in a
    320 x 240 picture, drives across it at 5 px per frame: for a while it hides most of the
    road's features and brings far stronger ones. Yields (frame, the true sway (dx, dy))."""
    texture = np.random.default_rng(5).normal(0, 14, (30, 40, 3)).astype(np.float32)
    road = np.float32(90) + cv2.resize(texture, (320, 240))
    squares = (np.indices((230, 300)) // 10).sum(axis=0) % 2
    van = np.where(squares[..., None] == 1, 230, 30).astype(np.float32)
    rng = np.random.default_rng(6)
    for n in range(frames):
        img = road.copy()
        x = -300 + 5 * n
        if x < 320:
            a, b = max(x, 0), min(x + 300, 320)
            if b > a:
                img[5:235, a:b] = van[:, a - x:b - x]
        dx, dy = 2.5 * np.sin(0.9 * n), 2.0 * np.sin(0.6 * n)
        img = cv2.warpAffine(img, np.float32([[1, 0, dx], [0, 1, dy]]), (320, 240),
                             borderMode=cv2.BORDER_REPLICATE)
        img += rng.normal(0, 2.0, img.shape).astype(np.float32)
        yield np.clip(img, 0, 255).astype(np.uint8), (dx, dy)


def test_robust_stabiliser_follows_the_camera_not_a_van_that_fills_the_view():
    """While the van hides most of the road, the default stabiliser loses its reference,
    takes the next frame -- the van's features -- for it and follows the van: its estimate
    of the sway runs hundreds of pixels off and never comes back. With `stabilise_robust`
    only features that follow the camera's last motion count, the reference is the road
    estimated from the video, and a frame with too few of them keeps the last estimate: the
    error stays within the sway's own range while the van covers the view and is gone once
    the road shows again."""
    errors = {}
    for robust in (False, True):
        det = MotionDetector(DetectorConfig(stabilise_robust=robust), 320, 240)
        det.initialise([f for f, _ in _van_scene(1)] * 3)
        err = []
        for img, (dx, dy) in _van_scene(140):
            det.detect(img)
            err.append(np.abs(det.stabiliser.M[:, 2] - (dx, dy)).max())
        errors[robust] = np.array(err)
    gone = slice(124, None)                  # the van has left the picture
    assert errors[True].max() < 5.0 and errors[True][gone].max() < 0.3, errors[True]
    assert errors[True][:20].max() < 0.3     # before it covers the road
    assert errors[False][gone].min() > 50.0, errors[False][gone]


def test_robust_stabiliser_aligns_background_samples_the_camera_moved_far_from():
    """The background is the median of frames sampled seconds apart, each aligned onto the
    first; a camera that drifted 8 px meanwhile is further from it than the robust fit's
    FOLLOW_PX (3 px here). Seeded at the identity alone, no feature followed, and such a
    sample went into the background unaligned; now the better of the seeded and the
    unseeded fit aligns it, as the default stabiliser does."""
    scene = Scene(320, 240, [], seed=5)
    first = scene.frame(0)
    moved = cv2.warpAffine(scene.frame(1), np.float32([[1, 0, 8.0], [0, 1, -5.0]]), (320, 240),
                           borderMode=cv2.BORDER_REPLICATE)
    inner = (slice(20, -20), slice(20, -20))
    off = np.abs(moved.astype(float) - first)[inner].mean()
    for robust in (False, True):
        stab = Stabiliser(320, 240, probe_frames=50, still_px=0.5, robust=robust)
        assert stab.align(first) is first                     # the first becomes the reference
        back = stab.align(moved)
        err = np.abs(back.astype(float) - first)[inner].mean()
        assert err < 0.2 * off, (robust, err, off)


def test_a_blob_cut_by_the_reference_border_stays_on_the_frame_border():
    """A camera that swayed 3 px right and 2 px down moves the reference's picture by that
    much: a blob on the reference's left and top border lands 3 and 2 px inside this
    frame, where the tracker would take it for the whole vehicle. Its edges on the
    reference's border go back to this frame's; an edge inside the picture keeps its
    warped place, and one beyond this frame's border is not pulled in."""
    m = np.array([[1.0, 0.0, 3.0], [0.0, 1.0, 2.0]])
    ref = np.array([[0.0, 0.0, 40.0, 30.0],       # on the top-left corner
                    [100.0, 50.0, 20.0, 10.0],    # inside
                    [300.0, 200.0, 20.0, 40.0]])  # on the right and bottom border
    kept = border_edges_kept(ref, transform_boxes(m, ref), 320, 240)
    np.testing.assert_allclose(kept, [[0, 0, 43, 32], [103, 52, 20, 10], [303, 202, 20, 40]])
    back = border_edges_kept(ref, transform_boxes(invert(m), ref), 320, 240)
    np.testing.assert_allclose(back, [[-3, -2, 40, 30], [97, 48, 20, 10], [297, 198, 23, 42]])


def test_stabiliser_probe_switches_off_for_a_still_camera_only():
    """The stabiliser estimates the camera's motion (Lucas-Kanade + RANSAC) over its first
    `probe_frames` frames; a camera whose image corners moved no more than `still_px` then
    costs almost nothing: the estimate runs only once a second (`stabilise_recheck_seconds`),
    each frame passes through unwarped with the identity, and the shift-tolerance stage
    stays off (`moved` is False). A camera that sways keeps the stabiliser on, every frame
    warped back onto the reference. Vehicles drive through both scenes during the probe."""
    probe = 20
    for shaken in (False, True):
        scene, rng = Scene(320, 240, RECTS, seed=3), np.random.default_rng(0)
        det = MotionDetector(DetectorConfig(warmup_frames=10), 320, 240, fps=probe / 2.0)
        stab = det.stabiliser
        assert stab.probe_frames == probe
        estimates = []
        estimate = stab.estimate
        stab.estimate = lambda small, guess=None: estimates.append(stab.frames) or estimate(
            small, guess)
        for n in range(START - 10, START + 30):      # the rectangles enter at frame 10
            img = _shaken(scene, n, rng)[0] if shaken else scene.frame(n)
            det.detect(img)
            assert det.foreground is not None
        if shaken:
            assert stab.active and stab.moved
            assert estimates == list(range(1, 41))            # every frame estimated
            small = det.prepare(_shaken(scene, START + 30, rng)[0])
            out, m = stab(small)
            assert out is not small and corner_shift(m, 320, 240) > 0.5
        else:
            assert not stab.active and not stab.moved
            # the probe's frames, then one a second (fps 10)
            assert estimates == list(range(1, probe + 1)) + [30, 40]
            small = det.prepare(scene.frame(START + 30))
            out, m = stab(small)
            assert out is small and np.array_equal(m, IDENTITY)
            assert len(estimates) == probe + 2


def test_stabiliser_switches_back_on_when_a_still_camera_starts_moving():
    """A camera still through the probe, knocked 3 px right and 2 px down at frame 35 (wind
    on the pole): the once-a-second checks (the 40th and 50th frames, 10 fps) find it moved
    twice in a row and switch the stabiliser back on, and from then every frame is warped
    back onto the reference, the image's content where it was. Without the check
    (`stabilise_recheck_seconds` 0) the frames pass through unaligned for the rest of the
    video."""
    knock = np.float32([[1, 0, 3.0], [0, 1, 2.0]])
    inner = (slice(20, -20), slice(20, -20))
    for recheck in (1.0, 0.0):
        scene = Scene(320, 240, [], seed=5)
        cfg = DetectorConfig(warmup_frames=10, stabilise_recheck_seconds=recheck)
        det = MotionDetector(cfg, 320, 240, fps=10.0)
        stab = det.stabiliser
        errors = []
        for n in range(60):
            img = scene.frame(n)
            if n >= 35:
                img = cv2.warpAffine(img, knock, (320, 240), borderMode=cv2.BORDER_REPLICATE)
            out, _ = stab(det.prepare(img))
            errors.append(np.abs(out.astype(float) - det.prepare(scene.frame(n)))[inner].mean())
        if recheck:
            assert stab.active and stab.moved
            assert max(errors[:35]) < 1.0 and max(errors[49:]) < 1.0, errors
            assert min(errors[35:49]) > 3.0, errors   # unaligned until the second check
        else:
            assert not stab.active and not stab.moved
            assert min(errors[40:]) > 3.0, errors


def test_shift_tolerance_blends_follow_their_definition():
    """ShiftTolerance._blends against its definition written out pixel pair by pixel pair
    (min(a, b) - t <= c <= max(a, b) + t in every channel, for some 4-adjacent pair a, b of
    the window, image edges replicated), on random colours near the background's and at
    the saturation limits 0 and 255."""
    from vtrack.vision.jitter import ShiftTolerance

    rng = np.random.default_rng(3)
    shift = ShiftTolerance(8.0, 2)
    for trial in range(6):
        if trial < 3:
            bg = np.clip(rng.normal(120, 10 + 30 * trial, (30, 40, 3)), 0, 255).astype(np.uint8)
        else:
            bg = rng.choice(np.array([0, 3, 9, 246, 250, 255], np.uint8), (30, 40, 3))
        ys, xs = rng.integers(0, 30, 400), rng.integers(0, 40, 400)
        colours = np.clip(bg[ys, xs].astype(int) + rng.integers(-30, 31, (400, 3)), 0, 255
                          ).astype(np.uint8)
        if trial >= 3:
            colours = rng.choice(np.array([0, 1, 8, 247, 254, 255], np.uint8), (400, 3))
        want = []
        for y, x, c in zip(ys, xs, colours.astype(int)):
            win = bg[np.clip(np.arange(y - 2, y + 3), 0, 29)][:, np.clip(
                np.arange(x - 2, x + 3), 0, 39)].astype(int)
            pairs = [(win[i, j], win[i, j + 1]) for i in range(5) for j in range(4)]
            pairs += [(win[i, j], win[i + 1, j]) for i in range(4) for j in range(5)]
            want.append(any(np.all((np.minimum(a, b) - 8 <= c) & (c <= np.maximum(a, b) + 8))
                            for a, b in pairs))
        got = shift._blends(colours, bg, ys, xs, 2)
        assert got.tolist() == want
        assert 0 < sum(want) < len(want) or trial >= 3


def test_shift_tolerance_of_a_large_radius_tests_the_small_window_first_with_one_result():
    """Radius 4 (the far band's, at twice the resolution) explains the pixels the radius-2
    window explains and then tests the rest with the full window: the same mask as the full
    window's test of every candidate."""
    import cv2

    from vtrack.vision.jitter import ShiftTolerance

    rng = np.random.default_rng(5)
    bg = cv2.GaussianBlur(rng.integers(0, 256, (60, 80, 3), dtype=np.uint8), (5, 5), 0)
    frame = np.clip(np.roll(bg, (3, -2), axis=(0, 1)).astype(int)
                    + rng.integers(-6, 7, bg.shape), 0, 255).astype(np.uint8)
    fg = np.where(rng.random((60, 80)) < 0.5, 255, 0).astype(np.uint8)
    shift = ShiftTolerance(8.0, 4)
    low, high = shift.bounds(bg)
    ys, xs = np.nonzero(cv2.bitwise_and(cv2.inRange(frame, low, high), fg))
    want = fg.copy()
    explained = shift._blends(frame[ys, xs], bg, ys, xs, 4)
    want[ys[explained], xs[explained]] = 0
    near = shift._blends(frame[ys, xs], bg, ys, xs, 2)
    assert near.sum() < explained.sum() and not (near & ~explained).any()
    assert np.array_equal(shift(fg, frame, bg), want)


def test_long_pieces_of_a_mask():
    """shadows._long keeps the 8-connected pieces whose box has a side of at least
    `length`, on sparse random masks (16-bit labels) and on a checkerboard of isolated
    pixels with more pieces than 16 bits can number (32-bit labels)."""
    from vtrack.vision.shadows import _long

    rng = np.random.default_rng(4)
    masks = [(rng.random((120, 200)) < p).astype(np.uint8) * 255 for p in (0.01, 0.3, 0.5)]
    masks.append(np.zeros((360, 800), np.uint8))
    masks[-1][::2, ::2] = 255                           # 72,000 isolated pixels
    masks[-1][100, 100:140] = 255                       # one long line through them
    for mask in masks:
        _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        keep = np.maximum(stats[:, 2], stats[:, 3]) >= 12
        keep[0] = False
        want = keep[labels].astype(np.uint8)
        got = _long(mask, 12)
        assert got.dtype == np.uint8 and np.array_equal(got, want)
    assert got.sum() == 41                              # and the grid pixel at its end
