"""Speed, length and class on a simulated perspective camera (sim_camera): vehicles of known
size and speed on a known road, projected into boxes, fed through a perfect tracker, a
box-filtering Kalman tracker of the core, and the real Tracker."""

from __future__ import annotations

import csv
import dataclasses
import tomllib

import numpy as np
import pytest
from sim_camera import BoxFilter, Scene

from vtrack.analytics.calibration import parse_calibration
from vtrack.analytics.traffic import TrafficAnalytics
from vtrack.tracking.tracker import Tracker, TrackerConfig


def _analytics(scene: Scene, out) -> TrafficAnalytics:
    cal = parse_calibration(tomllib.loads(scene.calibration_toml()), "calibration.toml")
    an = TrafficAnalytics(out, scene.camera.width, scene.camera.height, scene.fps,
                          calibration=cal)
    an.flush()
    return an


def _vehicles(out) -> list[dict]:
    with open(out / "vehicles.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _truth(scene: Scene, row: dict, vid: int) -> tuple[float, float]:
    """True mean and max speed (km/h) of vehicle `vid` over the row's frames."""
    t = (np.arange(int(row["first_frame"]), int(row["last_frame"]) + 1) - 1) / scene.fps
    v = 3.6 * scene.vehicles[vid - 1].speed(t)
    return float(np.mean(v)), float(np.max(v))


def _score(scene: Scene, rows: list[dict], id_of=lambda tid: tid) -> dict:
    e, emax, le, ok = [], [], [], []
    for r in rows:
        veh = scene.vehicles[id_of(int(r["id"])) - 1]
        mean, mx = _truth(scene, r, veh.id)
        e.append(float(r["speed_mean_kmh"]) - mean)
        emax.append(float(r["speed_max_kmh"]) - mx)
        le.append(float(r["length_m"]) - veh.length)
        ok.append(r["class"] == veh.kind)
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))  # noqa: E731
    return {"vehicles": len(rows), "speed_rmse": rms(e), "max_rmse": rms(emax),
            "length_rmse": rms(le), "length_bias": float(np.mean(le)),
            "class_accuracy": float(np.mean(ok))}


def _run_exact(scene: Scene, out, edit=lambda n, ft: ft) -> list[dict]:
    an = _analytics(scene, out)
    for n in range(1, scene.frames + 1):
        an.add_frame(n, scene.time(n), edit(n, scene.exact_tracks(n)))
    an.flush(final=True)
    return _vehicles(out)


def test_perfect_tracks_give_exact_speed_length_within_a_metre_and_every_class(tmp_path):
    """With exact states the speed is exact (the Jacobian at the ground point maps the filtered
    velocity; the box height's rate moves the ground point); the length is off only by the
    class's typical height against the vehicle's own."""
    results = []
    for seed in range(3):
        scene = Scene.make(seed, frames=500, vehicles=14)
        rows = _run_exact(scene, tmp_path / f"s{seed}")
        results.append(_score(scene, rows))
    s = {k: float(np.mean([r[k] for r in results])) for k in results[0]}
    print("perfect tracks:", {k: round(v, 3) for k, v in s.items()})
    assert s["vehicles"] >= 13
    assert s["speed_rmse"] < 0.1
    assert s["max_rmse"] < 2.0            # the 1 s mean vs the instantaneous true maximum
    assert s["length_rmse"] < 1.0
    assert s["class_accuracy"] == 1.0


def test_box_filter_on_noisy_boxes(tmp_path):
    """A tracker that filters the box (centre, size and their rates, core KF) on boxes whose
    edges jitter by 1 px: the figures the analytics reach on a well-behaved tracker."""
    results = []
    for seed in range(3):
        scene = Scene.make(seed, frames=500, vehicles=14)
        an = _analytics(scene, tmp_path / f"s{seed}")
        bf, rng = BoxFilter(noise_px=1.0), np.random.default_rng(seed)
        for n in range(1, scene.frames + 1):
            _, boxes, ids = scene.detections(n, rng, noise_px=1.0)
            for vid in set(bf.x) - {v.id for v, _, _ in scene.boxes(n)}:
                bf.drop(vid)                                   # left the image
            an.add_frame(n, scene.time(n), bf.step(n, scene.time(n), boxes, ids))
        an.flush(final=True)
        results.append(_score(scene, _vehicles(tmp_path / f"s{seed}")))
    s = {k: float(np.mean([r[k] for r in results])) for k in results[0]}
    print("box filter, 1 px noise:", {k: round(v, 3) for k, v in s.items()})
    assert s["speed_rmse"] < 8.0
    assert s["length_rmse"] < 1.5
    assert s["class_accuracy"] >= 0.9


def _one_car() -> Scene:
    """A car at a constant 58 km/h, in view from frame 16 to 160."""
    return Scene.make(3, frames=160, vehicles=1, kinds=("car",), wobble=0.0)


def test_a_coasting_stretch_cannot_swing_the_speed(tmp_path):
    """Frames in which the track coasts carry a prediction, here a badly drifting one (1.6x
    the velocity): they add no speed samples, so mean and max stay put."""
    scene = _one_car()
    clean = _run_exact(scene, tmp_path / "clean")

    def coast(n, ft):
        if 70 <= n < 85:                                       # 0.6 s
            st, rows = ft.states.copy(), ft.rows.copy()
            st[:, 2:4] *= 1.6
            rows[:, 6] = 0.5
            return dataclasses.replace(ft, states=st, rows=rows,
                                       coasted=np.ones(len(ft.ids), bool))
        return ft

    gap = _run_exact(scene, tmp_path / "gap", coast)
    assert len(clean) == len(gap) == 1
    for key in ("speed_mean_kmh", "speed_max_kmh", "length_m"):
        assert float(gap[0][key]) == pytest.approx(float(clean[0][key]), abs=0.05), key
    assert int(gap[0]["detected_frames"]) == int(clean[0]["detected_frames"]) - 15


def test_one_wild_frame_does_not_make_the_maximum(tmp_path):
    scene = _one_car()
    clean = _run_exact(scene, tmp_path / "clean")

    def spike(n, ft):
        if n == 80:
            st = ft.states.copy()
            st[:, 2:4] *= 3.0
            return dataclasses.replace(ft, states=st)
        return ft

    wild = _run_exact(scene, tmp_path / "wild", spike)
    true_speed = 3.6 * scene.vehicles[0].v0
    print(f"true {true_speed:.1f}, max clean {clean[0]['speed_max_kmh']}, "
          f"with a 3x frame {wild[0]['speed_max_kmh']}")
    assert float(wild[0]["speed_max_kmh"]) < true_speed * 1.1
    assert float(clean[0]["speed_max_kmh"]) == pytest.approx(true_speed, abs=0.5)


def _real_tracker_run(scene: Scene, out, hidden=range(0)) -> list[dict]:
    an = _analytics(scene, out)
    tracker = Tracker(TrackerConfig(), scene.camera.width, scene.camera.height)
    rng = np.random.default_rng(0)
    for n in range(1, scene.frames + 1):
        centres, boxes, _ = scene.detections(n, rng, noise_px=0.5)
        if n in hidden:
            centres, boxes = centres[:0], boxes[:0]
        an.add_frame(n, scene.time(n), tracker.step(n, scene.time(n), centres, boxes))
    an.flush(final=True)
    return _vehicles(out)


def test_real_tracker_brief_occlusion_keeps_the_speed(tmp_path):
    """The real Tracker, one car, its detections gone for 0.4 s in mid-view: one track, and
    its reported speed moves by less than 1.5 km/h."""
    scene = _one_car()
    clean = _real_tracker_run(scene, tmp_path / "clean")
    gap = _real_tracker_run(scene, tmp_path / "gap", hidden=range(80, 90))
    assert len(clean) == len(gap) == 1
    a, b = float(clean[0]["speed_mean_kmh"]), float(gap[0]["speed_mean_kmh"])
    true_speed = 3.6 * scene.vehicles[0].v0
    print(f"true {true_speed:.1f} km/h; clean {a}, with a 0.4 s gap {b}")
    assert abs(a - b) < 1.5
    # Against the truth: 52.8 and 52.9 km/h for a true 58.0 when this was written (the
    # speed of the filtered centre's ground point, analytics/vehicles.py); within 12 %.
    for speed in (a, b):
        assert abs(speed - true_speed) <= 0.12 * true_speed
    assert abs(float(clean[0]["speed_max_kmh"]) - float(gap[0]["speed_max_kmh"])) < 3.0
