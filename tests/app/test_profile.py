"""`vtrack track --profile`: the per-stage table on stderr and in profile.json, whose stages
never sum to more than the run's wall time, and outputs byte-identical to a run without it."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from vtrack.app import profile

# stages every run of a swaying mast clip goes through (split and shift tolerance run only
# when vehicles merge or the camera has moved)
ALWAYS = (profile.START, profile.BACKGROUND, profile.DECODE, "prepare (downscale, blur)",
          "stabilise", "gain compensation", "MOG2", "shadows", "morphology", "motion map",
          "blobs", "tracker predict", "tracker update", profile.OUTPUTS, profile.UNACCOUNTED)


@pytest.fixture(scope="module")
def mast_clip(tmp_path_factory) -> Path:
    from vtrack.sim.clip import render_preset
    from vtrack.sim.nuisance import parse_nuisances

    out = tmp_path_factory.mktemp("mast")
    render_preset(out, "mast", frames=80, width=320, height=180, fps=25.0, seed=1,
                  nuisances=parse_nuisances("all"))
    return out / "video.avi"


def _track(video: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "vtrack", "track", str(video), "--out",
                           str(out), "--quiet", *extra], capture_output=True, text=True,
                          check=True)


def test_profile_table_and_identical_outputs(mast_clip, tmp_path):
    plain = _track(mast_clip, tmp_path / "plain")
    profiled = _track(mast_clip, tmp_path / "profiled", "--profile")
    _check_profile(profiled, tmp_path)
    # a run without --profile removes a stale profile.json
    _track(mast_clip, tmp_path / "profiled")
    assert not (tmp_path / "profiled" / "profile.json").exists()


def test_profile_with_the_standing_hold(mast_clip, tmp_path):
    """The detector's optional stages that use the tracker's predictions (the standing hold,
    the noise floor in vehicle units) give the same outputs timed in one thread."""
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[detector]\nhold_standing = true\nmin_vehicle_share = 0.3\n")
    _track(mast_clip, tmp_path / "plain", "--config", str(cfg))
    profiled = _track(mast_clip, tmp_path / "profiled", "--config", str(cfg), "--profile")
    assert "standing boxes" in _check_profile(profiled, tmp_path)


def _check_profile(profiled: subprocess.CompletedProcess, tmp_path: Path, frames: int = 80
                   ) -> dict[str, float]:
    """The table on stderr against profile.json and the wall time; the outputs of
    tmp_path/profiled byte-identical to tmp_path/plain's; returns the table."""
    # the table on stderr: a heading with the wall time, one row per stage
    head, *rows = profiled.stderr.strip().splitlines()
    wall_ms = float(re.search(r"([\d.]+) ms a frame", head).group(1))
    table = {}
    for row in rows:
        name, ms, share = re.fullmatch(r"\s+(.+?)\s+(-?[\d.]+) ms\s+(-?[\d.]+) %", row).groups()
        table[name] = float(ms)
    assert set(ALWAYS) <= set(table)
    assert all(ms >= 0 for ms in table.values())   # "not accounted" too: stages <= wall
    assert sum(table.values()) == pytest.approx(wall_ms, abs=0.01 * len(table))
    assert sum(ms for name, ms in table.items() if name != profile.UNACCOUNTED) <= wall_ms
    # profile.json holds the same stages, in seconds
    saved = json.loads((tmp_path / "profiled" / "profile.json").read_text())
    assert saved["frames"] == frames
    stages = {s["stage"]: s["seconds"] for s in saved["stages"]}
    assert list(stages) == list(table)
    assert sum(v for k, v in stages.items() if k != profile.UNACCOUNTED) \
        <= saved["wall_seconds"]
    # every output byte-identical; summary.json differs only in the measured speed
    files = sorted(p.name for p in (tmp_path / "plain").iterdir())
    assert files == sorted(p.name for p in (tmp_path / "profiled").iterdir()
                           if p.name != "profile.json")
    for name in files:
        a, b = ((tmp_path / run / name).read_bytes() for run in ("plain", "profiled"))
        if name == "summary.json":
            a, b = (dict(json.loads(x), fps_processed=0) for x in (a, b))
        assert a == b, name
    return table


def test_instrumented_restores_the_detector_module():
    from vtrack.vision import detect

    before = detect.find_blobs, detect.textured_shadow
    with pytest.raises(RuntimeError):
        with profile.instrumented(object(), object(), profile.StageTimes()):
            assert detect.find_blobs is not before[0]
            raise RuntimeError
    assert (detect.find_blobs, detect.textured_shadow) == before


def test_profile_with_the_far_band(tmp_path):
    """The far band (a second detector on the top rows at full resolution, started by the
    tracked boxes 78 frames into this 1280x720 mast clip, of which 110 frames are read) gives the same outputs in the
    threaded pipeline as timed in one thread, its time a stage of its own."""
    from vtrack.sim.clip import render_preset
    from vtrack.sim.nuisance import parse_nuisances

    render_preset(tmp_path / "clip", "mast", frames=300, width=1280, height=720, fps=25.0,
                  seed=108, nuisances=parse_nuisances("all"))
    video = tmp_path / "clip" / "video.avi"
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[detector]\nfar_band = true\n")
    run = ("--max-frames", "110", "--save-detections")
    _track(video, tmp_path / "plain", "--config", str(cfg), *run)
    profiled = _track(video, tmp_path / "profiled", "--config", str(cfg), "--profile", *run)
    table = _check_profile(profiled, tmp_path, frames=110)
    assert table[profile.FAR_BAND] > 0
    # the band found blobs of its own: more detections than without it
    _track(video, tmp_path / "off", *run)
    band = (tmp_path / "plain" / "detections.csv").read_text().splitlines()
    assert len(band) > len((tmp_path / "off" / "detections.csv").read_text().splitlines())
