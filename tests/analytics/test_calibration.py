"""Ground calibration: normalised DLT against exact correspondences, degenerate inputs, the
Jacobian's road velocity, and the camera recovered from the homography."""

from __future__ import annotations

import numpy as np
import pytest
from sim_camera import Camera, Scene

from vtrack.analytics.calibration import (Calibration, apply_homography, fit_homography, load_calibration,
                                          parse_calibration)
from vtrack.analytics.camera import camera_from_homography
from vtrack.errors import InputError

ROAD = np.array([(-7.0, 12.0), (7.0, 12.0), (-7.0, 30.0), (7.0, 30.0), (-3.5, 60.0),
                 (3.5, 60.0), (0.0, 20.0), (5.0, 45.0)])


def _camera(**kw) -> Camera:
    return Camera.mast(**kw)


def _image_of(cam: Camera, world: np.ndarray) -> np.ndarray:
    return cam.project(np.column_stack([world, np.zeros(len(world))]))[0]


@pytest.mark.parametrize("n", [4, 6, 8])
def test_dlt_recovers_the_exact_homography(n):
    cam = _camera(cam_x=3.0, look_y=30.0)
    H_true = cam.image_to_ground()
    image = _image_of(cam, ROAD[:n])
    H = fit_homography(image, ROAD[:n])
    assert np.allclose(H, H_true, rtol=1e-8, atol=1e-10)
    probe = np.array([[100.0, 300.0], [500.0, 200.0], [320.0, 150.0]])
    assert np.allclose(apply_homography(H, probe), apply_homography(H_true, probe), atol=1e-6)


def test_least_squares_with_noisy_points_beats_four_points():
    cam = _camera()
    rng = np.random.default_rng(3)
    grid = np.array([(x, y) for x in (-7.0, -3.5, 0.0, 3.5, 7.0) for y in (14.0, 22.0, 35.0)])
    image = _image_of(cam, grid) + rng.normal(0, 0.7, (len(grid), 2))
    probe = np.array([(x, y) for x in (-6.0, 0.0, 6.0) for y in (15.0, 25.0, 33.0)])
    truth = probe

    def err(H):
        return np.sqrt(np.mean(np.sum((apply_homography(H, _image_of(cam, probe)) - truth) ** 2,
                                      axis=1)))

    corners = [0, 2, 12, 14]          # the 4 outer points
    e4, e15 = err(fit_homography(image[corners], grid[corners])), err(fit_homography(image, grid))
    print(f"road error at probe points: 4 points {e4:.3f} m, 15 points {e15:.3f} m")
    assert e15 < e4
    cal = Calibration(fit_homography(image, grid), image, grid)
    assert 0.3 < cal.errors()["reprojection_rms_px"] < 1.2   # about the noise, 0.7 px/axis


def test_jacobian_maps_image_velocity_to_road_velocity():
    """A point on the road moving at V (m/s) moves in the image at J^-1 V: the Jacobian at
    its image position maps its image velocity (finite differences of the projection) back."""
    cam = _camera(cam_x=2.0)
    cal = parse_calibration({"points": [{"image": list(i), "world": list(w)} for i, w in
                                        zip(_image_of(cam, ROAD[:6]), ROAD[:6])]}, "c")
    for X, V in [((1.0, 20.0), (0.0, -25.0)), ((-5.0, 40.0), (3.0, 12.0)),
                 ((6.0, 15.0), (-8.0, 0.5))]:
        X, V = np.array(X), np.array(V)
        dt = 1e-4
        p0, p1 = _image_of(cam, np.array([X - V * dt, X + V * dt]))
        v_img = (p1 - p0) / (2 * dt)
        v_road = cal.ground_velocity(_image_of(cam, X[None])[0], v_img)
        assert np.allclose(v_road, V, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("kw", [{}, {"cam_height": 6.0, "look_y": 25.0},
                                {"cam_x": 8.0, "cam_height": 12.0, "hfov_deg": 40.0},
                                {"width": 1280, "height": 720, "cam_x": -4.0}])
def test_camera_recovered_from_the_homography(kw):
    cam = _camera(**kw)
    rec = camera_from_homography(cam.image_to_ground(), cam.width, cam.height)
    assert rec is not None
    assert rec.height == pytest.approx(cam.C[2], rel=1e-6)
    assert np.allclose(rec.position, cam.C[:2], atol=1e-5)
    assert rec.focal == pytest.approx(cam.K[0, 0], rel=1e-6)


def test_straight_down_view_has_no_camera_to_recover():
    """An orthographic-like scale homography (the overhead synth scene) gives None."""
    H = np.diag([0.05, 0.05, 1.0])
    assert camera_from_homography(H, 640, 360) is None


def _write(tmp_path, text: str):
    p = tmp_path / "calib.toml"
    p.write_text(text)
    return p


def _points(pairs) -> str:
    return "".join(f"[[points]]\nimage = {list(i)}\nworld = {list(w)}\n" for i, w in pairs)


GOOD = [((100, 300), (0, 0)), ((500, 300), (10, 0)), ((420, 150), (10, 30)),
        ((200, 150), (0, 30))]


def test_a_good_file_loads(tmp_path):
    cal = load_calibration(_write(tmp_path, "frame_size = [640, 360]\n" + _points(GOOD)))
    assert cal.frame_size == (640, 360)
    assert cal.errors()["reprojection_rms_px"] < 1e-6
    cal.check_frame_size(640, 360)
    with pytest.raises(InputError, match=r"calib.toml: frame_size \[640, 360\] differs"):
        cal.check_frame_size(1280, 720)


@pytest.mark.parametrize("text, message", [
    (_points(GOOD[:3]), "at least 4"),
    (_points(GOOD[:3] + [((300, 300), (5, 0))]),
     r"fix no homography: no 4 of the 4 are in general position in image coordinates "
     r"\(points 1, 2, 4 lie on one line and only point 3 is off it"),
    (_points(GOOD[:3] + [((100, 300), (3, 9))]), r"image coordinates \(only 3 distinct"),
    (_points(GOOD[:3] + [((150, 250), (5, 0))]), "general position in world coordinates"),
    (_points(GOOD).replace("image = [100, 300]", "image = [100]"), "two finite numbers"),
    (_points(GOOD).replace("world = [0, 0]", 'world = ["a", 0]'), "two finite numbers"),
    (_points(GOOD).replace("image = [100, 300]\n", ""), "must have exactly image"),
    ("frame_size = [640]\n" + _points(GOOD), "frame_size must be two positive integers"),
    ("scale = 2\n" + _points(GOOD), "unknown key 'scale'"),
    ("points = 3\n", "needs \\[\\[points\\]\\]"),
    ("[[points]\n", "malformed TOML"),
])
def test_bad_calibrations_name_the_file(tmp_path, text, message):
    with pytest.raises(InputError, match=message) as err:
        load_calibration(_write(tmp_path, text))
    assert str(tmp_path / "calib.toml") in str(err.value)


def test_cli_rejects_a_bad_calibration_before_writing_anything(tmp_path, synth_video, capsys):
    from vtrack.cli import main

    src = synth_video(0)
    bad = _write(tmp_path, _points(GOOD[:3]))
    out = tmp_path / "run"
    assert main(["track", str(src / "video.avi"), "--out", str(out), "--quiet",
                 "--calibration", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and str(bad) in err[0]
    assert not out.exists()
    wrong = _write(tmp_path, "frame_size = [1280, 720]\n" + _points(GOOD))
    assert main(["track", str(src / "video.avi"), "--out", str(out), "--quiet",
                 "--calibration", str(wrong)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(wrong) in err[0] and "640x360" in err[0]
    assert not out.exists()


def test_scene_calibration_file_matches_its_camera():
    """The simulated scene's calibration.toml reproduces its camera's homography."""
    import tomllib

    scene = Scene.make(0, frames=10)
    cal = parse_calibration(tomllib.loads(scene.calibration_toml()), "scene")
    probe = _image_of(scene.camera, ROAD)                   # pixels given to 0.001 px
    assert np.allclose(cal.to_world(probe), ROAD, atol=0.01)


def _lane_points(cam: Camera, world: np.ndarray) -> str:
    return _points(zip((tuple(round(float(v), 3) for v in p) for p in _image_of(cam, world)),
                       (tuple(float(v) for v in w) for w in world)))


# Six points on three lane lines (X = -3.5, 0, 3.5), near and far: every line holds a
# collinear pair, and with a seventh point on the middle line, a collinear triple.
LANES = np.array([(-3.5, 15.0), (-3.5, 45.0), (0.0, 15.0), (0.0, 45.0), (3.5, 15.0),
                  (3.5, 45.0)])


@pytest.mark.parametrize("world", [LANES, np.vstack([LANES, [(0.0, 30.0)]])])
def test_points_measured_along_lane_lines_are_accepted(tmp_path, world):
    """The issue's case: points along lane markings (collinear triples in image and on the
    road) fix the homography; the fit over all of them reproduces the camera's."""
    cam = _camera(cam_x=2.0)
    cal = load_calibration(_write(tmp_path, _lane_points(cam, world)))
    err = cal.errors()
    assert err["points"] == len(world)
    assert err["reprojection_px"]["max"] < 0.01 and err["reprojection_m"]["max"] < 0.01
    assert 0 <= err["reprojection_px"]["mean"] <= err["reprojection_px"]["max"]
    probe = np.array([(-6.0, 20.0), (5.0, 60.0), (1.0, 12.0)])
    assert np.allclose(cal.to_world(_image_of(cam, probe)), probe, atol=0.02)
    assert cal.warning() is None


def test_a_misplaced_point_is_reported_by_its_error_and_warned(tmp_path):
    """A point whose metres are typed 3 m wrong: accepted, its error shows in px and m, and
    the warning names it."""
    cam = _camera(cam_x=2.0)
    world = np.vstack([LANES, [(0.0, 30.0)]])
    typed = world.copy()
    typed[6, 1] += 3.0
    text = _points(zip((tuple(round(float(v), 3) for v in p) for p in _image_of(cam, world)),
                       (tuple(float(v) for v in w) for w in typed)))
    cal = load_calibration(_write(tmp_path, text))
    err = cal.errors()
    assert err["reprojection_m"]["max"] > 0.5 and err["reprojection_px"]["max"] > 1.0
    message = cal.warning()
    assert message is not None and "fit no homography well" in message
    assert str(tmp_path / "calib.toml") in message


@pytest.mark.parametrize("world, message", [
    # all on one lane line
    ([(0.0, 10.0), (0.0, 20.0), (0.0, 30.0), (0.0, 40.0), (0.0, 50.0)],
     "points 1, 2, 3, 4, 5 lie on one line"),
    # four on a line, one off: every 4 of them hold a collinear triple
    ([(0.0, 10.0), (0.0, 20.0), (0.0, 30.0), (0.0, 40.0), (3.5, 20.0)],
     "only point 5 is off it"),
    # coincident points: two places only, plus one
    ([(0.0, 10.0), (0.0, 10.0), (3.5, 30.0), (3.5, 30.0), (-3.5, 20.0)],
     "only 3 distinct points"),
])
def test_sets_that_fix_no_homography_are_refused_with_one_line(tmp_path, world, message,
                                                               capsys):
    from vtrack.cli import main

    cam = _camera(cam_x=2.0)
    bad = _write(tmp_path, _lane_points(cam, np.array(world)))
    with pytest.raises(InputError, match=message):
        load_calibration(bad)
    out = tmp_path / "run"
    assert main(["track", str(tmp_path / "none.avi"), "--out", str(out), "--quiet",
                 "--calibration", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and str(bad) in err[0]
    assert "fix no homography" in err[0] and not out.exists()


def test_general_quadruple_finds_one_among_collinear_triples():
    from vtrack.analytics.calibration import general_quadruple

    pts = np.array([(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1)], dtype=float)
    quad = general_quadruple([pts])
    assert quad is not None and len(set(quad)) == 4
    assert general_quadruple([pts[[0, 1, 2, 3]]]) is None


def test_track_warns_once_on_a_poor_fit_and_reports_its_error(tmp_path, synth_video, capsys):
    """`vtrack track` with a calibration whose seventh point's metres are 3 m off: it runs,
    says so on one `warning:` line, and summary.json has the reprojection errors."""
    import json

    from vtrack.cli import main

    cam = _camera(cam_x=2.0)
    world = np.vstack([LANES, [(0.0, 30.0)]])
    typed = world.copy()
    typed[6, 1] += 3.0
    calib = _write(tmp_path, _points(zip(
        (tuple(round(float(v), 3) for v in p) for p in _image_of(cam, world)),
        (tuple(float(v) for v in w) for w in typed))))
    out = tmp_path / "run"
    assert main(["track", str(synth_video(0) / "video.avi"), "--out", str(out), "--quiet",
                 "--max-frames", "5", "--calibration", str(calib)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("warning: ") and str(calib) in err[0]
    cal = json.loads((out / "summary.json").read_text())["calibration"]
    assert cal["points"] == 7 and cal["reprojection_m"]["max"] > 0.5
    assert cal["reprojection_px"]["mean"] <= cal["reprojection_px"]["max"]
