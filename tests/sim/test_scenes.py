"""The perspective scene presets of `vtrack synth`: files, ground truth against the pixels and
the camera, perspective, occlusion, queues, the vehicle mix and determinism."""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace

import cv2
import numpy as np
import pytest

from vtrack.cli import main
from vtrack.sim.camera import Camera
from vtrack.sim.clip import ClipRenderer, build_scene, render_preset
from vtrack.sim.dynamics import Motion
from vtrack.sim.groundtruth import Seen, frame_rows
from vtrack.sim.nuisance import NUISANCES
from vtrack.sim.population import populate
from vtrack.sim.render import Buffers, Light, Placed, draw_all, silhouette
from vtrack.sim.scenes import build_layout
from vtrack.sim.shapes import place
from vtrack.sim.vehicles import KINDS, draw_vehicle

W, H, FRAMES = 320, 180, 60
ALL = frozenset(NUISANCES)
CLASSES = {"motorcycle", "car", "van", "truck"}


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    """Each preset rendered once, small, with every nuisance but shake: preset -> folder."""
    out = {}
    for preset in ("mast", "side", "junction"):
        folder = tmp_path_factory.mktemp(preset)
        render_preset(folder, preset, frames=FRAMES, width=W, height=H, seed=3,
                      nuisances=ALL - {"shake"})
        out[preset] = folder
    return out


@pytest.fixture(scope="module")
def shaken(tmp_path_factory):
    """A mast clip with every nuisance, shake included."""
    folder = tmp_path_factory.mktemp("shaken")
    render_preset(folder, "mast", frames=FRAMES, width=W, height=H, seed=3, nuisances=ALL)
    return folder


def _gt(folder):
    return np.loadtxt(folder / "gt.csv", delimiter=",", ndmin=2)


def _world(folder):
    lines = (folder / "world.csv").read_text().splitlines()
    assert lines[0] == "frame,id,X_m,Y_m,speed_kmh,length_m,class"
    rows = [line.split(",") for line in lines[1:]]
    return (np.array([[float(v) for v in r[:6]] for r in rows]).reshape(-1, 6),
            [r[6] for r in rows])


def _homography(folder):
    calib = tomllib.loads((folder / "calibration.toml").read_text())
    img = np.array([p["image"] for p in calib["points"]], float)
    world = np.array([p["world"] for p in calib["points"]], float)
    return calib, img, world, cv2.findHomography(world, img)[0]


@pytest.mark.parametrize("preset", ["mast", "side", "junction"])
def test_preset_writes_video_gt_world_and_calibration(clips, preset):
    folder = clips[preset]
    assert sorted(p.name for p in folder.iterdir()) == ["calibration.toml", "gt.csv",
                                                       "video.avi", "world.csv"]
    cap = cv2.VideoCapture(str(folder / "video.avi"))
    count = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        assert frame.shape == (H, W, 3)
        count += 1
    assert count == FRAMES
    gt = _gt(folder)
    assert gt.shape[1] == 11 and len(gt) > FRAMES          # several vehicles in view
    assert np.array_equal(np.lexsort((gt[:, 1], gt[:, 0])), np.arange(len(gt)))
    left, top, w, h = gt[:, 2:6].T
    assert np.all((left >= 0) & (top >= 0) & (w > 0) & (h > 0))
    assert np.all((left + w <= W) & (top + h <= H))
    assert np.all(gt[:, 6] == 1) and np.all(gt[:, 7:10] == -1)
    assert np.all((gt[:, 10] >= 0) & (gt[:, 10] <= 1))
    world, classes = _world(folder)
    assert np.array_equal(world[:, :2], gt[:, :2]), "one world row per gt row"
    assert set(classes) <= CLASSES
    calib, img, pts, _ = _homography(folder)
    assert calib["frame_size"] == [W, H] and len(pts) >= 4
    for a, b, c in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        (ux, uy), (vx, vy) = img[b] - img[a], img[c] - img[a]
        area = abs(ux * vy - uy * vx) / 2
        assert area > 0.01 * W * H, "no three calibration points are (nearly) collinear"


def test_vehicles_are_in_view_in_frame_1_only_with_inview(clips):
    in_first = sum(int(np.sum(_gt(folder)[:, 0] == 1)) for folder in clips.values())
    assert in_first >= 3
    for preset in ("mast", "side", "junction"):
        on_road = ~np.isnan(build_scene(preset, 2, None, W, H, 25.0, 3, ALL).motion.s[:, 0])
        assert on_road.sum() >= 3
        later = build_scene(preset, 2, None, W, H, 25.0, 3, ALL - {"inview", "parked"})
        assert np.isnan(later.motion.s[:, 0]).all()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mast_box_areas_span_four_times_between_far_and_near(seed):
    """The same vehicle's fully visible GT box grows at least 4x from the far to the near
    end of the visible road."""
    sc = build_scene("mast", 100, None, W, H, 10.0, seed, frozenset({"inview", "mix"}))
    areas: dict[int, list[float]] = {}
    for _, rows in ClipRenderer(sc, seed).frames():
        for r in rows:
            if r.visible == 1.0:
                areas.setdefault(r.vehicle, []).append(r.width * r.height)
    span = max(max(a) / min(a) for a in areas.values())
    assert span >= 4.0, f"largest far-to-near area ratio {span:.2f}"


@pytest.mark.parametrize("preset", ["mast", "side", "junction"])
def test_world_positions_project_into_their_gt_boxes(clips, preset):
    """Without shake, the road-plane centre of each fully visible vehicle, mapped through
    the homography of calibration.toml, lies inside its GT box."""
    gt = _gt(clips[preset])
    world, _ = _world(clips[preset])
    _, _, _, hom = _homography(clips[preset])
    full = gt[:, 10] == 1.0
    assert full.sum() >= 10
    px = cv2.perspectiveTransform(world[full, 2:4].reshape(-1, 1, 2), hom).reshape(-1, 2)
    left, top, w, h = gt[full, 2:6].T
    inside = ((px[:, 0] >= left - 1) & (px[:, 0] <= left + w + 1) & (px[:, 1] >= top - 1)
              & (px[:, 1] <= top + h + 1))
    assert inside.all(), f"{(~inside).sum()} of {len(inside)} centres outside their boxes"


def test_world_positions_stay_near_gt_boxes_under_shake(shaken):
    """With shake the boxes move with the image (GT is what the camera sees) while the
    calibration is the unshaken camera's: the centres stay within a few pixels."""
    gt = _gt(shaken)
    world, _ = _world(shaken)
    _, _, _, hom = _homography(shaken)
    full = gt[:, 10] == 1.0
    px = cv2.perspectiveTransform(world[full, 2:4].reshape(-1, 1, 2), hom).reshape(-1, 2)
    left, top, w, h = gt[full, 2:6].T
    outside = np.maximum.reduce([left - px[:, 0], px[:, 0] - left - w, top - px[:, 1],
                                 px[:, 1] - top - h, np.zeros(len(px))])
    assert outside.max() <= 8.0


def test_calibration_matches_the_camera(clips):
    """calibration.toml's pixels are the exact projections of its road-plane points."""
    sc = build_scene("side", FRAMES, None, W, H, 25.0, 3, ALL)
    _, img, world, _ = _homography(clips["side"])
    px = sc.layout.camera.project(np.column_stack([world, np.zeros(len(world))]))
    assert np.abs(px - img).max() < 0.01


def _two_cars(gap_across: float) -> list[tuple[int, float]]:
    """Two cars on the road in front of a camera, the near one shifted across by
    gap_across: (vehicle index, visible) from the GT of one drawn frame."""
    cam = Camera.looking((0.0, -25.0, 6.0), math.pi / 2, math.radians(12), 0.0, 250.0, W, H)
    rng = np.random.default_rng(0)
    cars = [draw_vehicle(rng, "van"), draw_vehicle(rng, "car")]
    light = Light(np.array([0.3, 0.3, 0.9]) / np.linalg.norm([0.3, 0.3, 0.9]), 0.6, 0.5, 0.5)
    buf = Buffers.start(np.full((H, W, 3), 90, np.uint8))
    placed = []
    for i, (veh, y) in enumerate(zip(cars, (3.0, -3.0))):        # far lane first
        x = -veh.length / 2 + (gap_across if i == 1 else 0.0)
        world, normals = place(veh.mesh, np.array([[x, y]]), np.array([0.0]))
        placed.append(Placed(veh.mesh, world, normals, i + 1))
    seen = [Seen(p.ident - 1, *silhouette(h)) for p, h in
            zip(placed, draw_all(buf, cam, light, placed))]
    return [(r.vehicle, r.visible) for r in frame_rows(seen, buf.ids, (0, 0))]


def test_visible_fraction_drops_when_a_vehicle_passes_in_front():
    apart = dict(_two_cars(8.0))
    together = dict(_two_cars(0.0))
    assert apart == {0: 1.0, 1: 1.0}
    assert together[1] == 1.0 and together[0] < 0.9


def test_side_scene_near_lane_hides_far_lane():
    """In a side clip some vehicle fully inside the image is mostly hidden by a nearer one
    whose box covers it."""
    sc = build_scene("side", 60, None, W, H, 10.0, 1, frozenset({"inview", "mix"}))
    cam = sc.layout.camera
    found = 0
    for n, (_, rows) in enumerate(ClipRenderer(sc, 1).frames()):
        active, centres = sc.centres(n)
        dist = dict(zip(active.tolist(), cam.distance(np.column_stack(
            [centres, np.ones(len(active))])).tolist()))
        for r in rows:
            if (r.visible > 0.6 or r.left == 0 or r.top == 0 or r.left + r.width == W
                    or r.top + r.height == H):
                continue
            for q in rows:
                ix = max(0, min(r.left + r.width, q.left + q.width) - max(r.left, q.left))
                iy = max(0, min(r.top + r.height, q.top + q.height) - max(r.top, q.top))
                if (q.vehicle != r.vehicle and dist[q.vehicle] < dist[r.vehicle]
                        and ix * iy >= 0.4 * r.width * r.height):
                    found += 1
    assert found >= 5


def test_junction_queue_stands_for_seconds_then_drives_off(tmp_path):
    fps, waited = 10.0, []
    render_preset(tmp_path, "junction", frames=90, width=W, height=H, fps=fps, seed=0,
                  nuisances=frozenset({"inview", "mix"}))
    world, _ = _world(tmp_path)
    for vid in np.unique(world[:, 1]):
        mine = world[world[:, 1] == vid]
        still = mine[:, 4] < 0.5
        if not still[0] and not still.any():
            continue
        run, best = 0, 0
        for n in range(len(mine)):
            run = run + 1 if still[n] else 0
            if run and np.any(mine[n:, 4] > 8.0):
                best = max(best, run)
        waited.append(best / fps)
    assert max(waited) >= 2.0, "a vehicle stands >= 2 s in view and later drives at 8 km/h"


def test_parked_vehicles_stand_then_pull_out():
    """With `parked`, vehicles stand on the shoulder from frame 1 and most pull out into the
    traffic during a 12 s clip."""
    moved = parked = 0
    for preset, seed in (("mast", 0), ("mast", 3), ("side", 1), ("side", 5)):
        sc = build_scene(preset, 120, None, W, H, 10.0, seed, ALL)
        for k in np.nonzero(np.isneginf(sc.drivers.enter_at))[0]:
            v = sc.motion.v[k]
            assert np.all(v[:10] == 0), "standing for the first second"
            parked += 1
            moved += bool(np.any(v > 3.0))
    assert parked >= 4 and moved >= parked / 2


def test_turning_paths_curve():
    layout = build_layout("junction", np.random.default_rng(2), W, H, False)
    assert any(any(k != 0 for k, _ in p.pieces) for p in layout.paths)


def test_vehicle_mix_has_every_class_with_its_sizes():
    kinds = []
    for preset in ("mast", "side", "junction"):
        for seed in range(3):
            rng = np.random.default_rng(seed)
            layout = build_layout(preset, rng, W, H, True)
            kinds += [v.kind for v in populate(rng, layout, 12.0, 20, 1.8, True, True, True)[1]]
    assert set(kinds) == CLASSES
    rng = np.random.default_rng(1)
    for kind in CLASSES:
        veh = draw_vehicle(rng, kind, articulated_share=0.0)
        lo, hi = KINDS[kind].length
        assert lo <= veh.length <= hi
        extent = np.ptp(veh.mesh.points, axis=0)
        assert extent[0] == pytest.approx(veh.length, abs=0.05)
    truck = draw_vehicle(rng, "truck", articulated_share=1.0)
    assert len(truck.units) == 2 and truck.length > 15
    rng = np.random.default_rng(0)
    layout = build_layout("side", rng, W, H, True)
    assert {v.kind for v in populate(rng, layout, 12.0, 20, 1.8, True, True, False)[1]} == {"car"}


def test_lanes_never_overlap():
    """Vehicles following one path keep a positive gap (IDM with leaders on the road)."""
    for preset in ("mast", "junction"):
        sc = build_scene(preset, 150, None, W, H, 25.0, 5, ALL)
        s, path = sc.motion.s, sc.drivers.path
        length = np.array([v.length for v in sc.fleet])
        for n in range(0, 150, 5):
            for p in np.unique(path):
                ks = np.nonzero((path == p) & ~np.isnan(s[:, n]))[0]
                front = np.sort(s[ks, n])
                order = ks[np.argsort(s[ks, n])]
                gaps = front[1:] - length[order[1:]] - front[:-1]
                assert np.all(gaps > -0.2), f"{preset} frame {n} path {p}"


def test_same_seed_same_bytes(shaken, tmp_path):
    render_preset(tmp_path, "mast", frames=FRAMES, width=W, height=H, seed=3, nuisances=ALL)
    for name in ("gt.csv", "world.csv", "calibration.toml", "video.avi"):
        assert (tmp_path / name).read_bytes() == (shaken / name).read_bytes()
    other = tmp_path / "other"
    render_preset(other, "mast", frames=FRAMES, width=W, height=H, seed=4, nuisances=ALL)
    assert (other / "gt.csv").read_bytes() != (tmp_path / "gt.csv").read_bytes()


def test_pixels_outside_gt_boxes_are_background():
    """Without shadows, sway and image nuisances, every pixel that differs from the empty
    scene lies in (or within 2 px of) some vehicle's GT box. The outermost pixel ring is
    left out: an anti-aliased edge of a vehicle just outside the image may tint it."""
    sc = build_scene("mast", 40, None, W, H, 25.0, 6, frozenset({"inview", "mix"}))
    nobody = replace(sc, motion=Motion(*np.full((3,) + sc.motion.s.shape, np.nan)))
    empty = (image for image, _ in ClipRenderer(nobody, 6).frames())
    for n, (image, rows) in enumerate(ClipRenderer(sc, 6).frames()):
        changed = np.abs(image.astype(int) - next(empty).astype(int)).max(axis=2) > 0
        changed[[0, -1], :] = changed[:, [0, -1]] = False
        boxes = np.zeros_like(changed)
        for r in rows:
            boxes[max(r.top - 2, 0):r.top + r.height + 2,
                  max(r.left - 2, 0):r.left + r.width + 2] = True
        assert not np.any(changed & ~boxes), f"frame {n + 1}"


@pytest.mark.parametrize("args", [["--scene", "roundabout"], ["--scene", "mast", "--nuisance",
                                                                "shake,fog"],
                                  ["--nuisance", "shake"]])
def test_unknown_scene_or_nuisance_is_bad_input(tmp_path, capsys, args):
    assert main(["synth", str(tmp_path / "x"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")
    assert not (tmp_path / "x").exists()


def test_cli_renders_a_preset(tmp_path, capsys):
    assert main(["synth", str(tmp_path), "--scene", "junction", "--frames", "5", "--width",
                 "200", "--height", "120", "--nuisance", "none", "--vehicles", "3"]) == 0
    assert "calibration.toml" in capsys.readouterr().out
    assert (tmp_path / "world.csv").read_text().startswith("frame,id,X_m,Y_m")
