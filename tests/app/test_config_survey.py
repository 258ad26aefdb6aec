"""The config keys the set-up page writes: `roi` (with `roi_units`) masks the detector's
foreground; `calibration` (relative to the config file) is used by `vtrack track --config`
unless `--calibration` overrides it; `vtrack config --defaults` and `--check` know both."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from vtrack.app import config
from vtrack.cli import main
from vtrack.errors import InputError
from vtrack.evaluation.mot import read_mot


def test_roi_and_calibration_parse_and_resolve(tmp_path):
    (tmp_path / "site.toml").write_text(
        'roi = [[0, 0], [0.5, 0], [0.5, 1], [0, 1]]\nroi_units = "fraction"\n'
        'calibration = "cal/site.calibration.toml"\n')
    cfg = config.load(tmp_path / "site.toml")
    assert cfg.roi.units == "fraction"
    assert np.array_equal(cfg.roi.pixels(640, 360), [[0, 0], [320, 0], [320, 360], [0, 360]])
    assert cfg.calibration == str(tmp_path / "cal" / "site.calibration.toml")


@pytest.mark.parametrize("text, message", [
    ('roi_units = "px"\n', "roi_units without roi"),
    ("roi = [[0, 0], [1, 1]]\n", "at least 3 vertices"),
    ('roi = [[0, 0], [2, 0], [0, 1]]\nroi_units = "fraction"\n', "within 0..1"),
    ("roi = [[0, 0], [10, 10], [10, 0], [0, 10]]\n", "edges cross"),
    ("calibration = 3\n", "calibration must be the path"),
])
def test_bad_roi_or_calibration_is_an_input_error(tmp_path, text, message):
    (tmp_path / "c.toml").write_text(text)
    with pytest.raises(InputError, match=message):
        config.load(tmp_path / "c.toml")


def test_config_defaults_and_check_know_the_keys(tmp_path, cli_stdout, overhead_truth, capsys):
    text = cli_stdout(["config", "--defaults"])
    assert "# roi = [[" in text and "# roi_units =" in text and "# calibration =" in text
    overhead_truth(0, tmp_path)
    (tmp_path / "ok.toml").write_text('roi = [[0, 0], [100, 0], [100, 100]]\n'
                                      'calibration = "calibration.toml"\n')
    assert "ok" in cli_stdout(["config", "--check", str(tmp_path / "ok.toml")])
    (tmp_path / "missing.toml").write_text('calibration = "nowhere.toml"\n')
    assert main(["config", "--check", str(tmp_path / "missing.toml")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "nowhere.toml" in err[0]


def test_roi_masks_the_detector(synth_video, tmp_path):
    """Only the left half of the frame is of interest: no detection reaches into the right
    half (the mask cuts blobs at the ROI's edge), and vehicles are still tracked there."""
    clip = synth_video(0) / "video.avi"
    (tmp_path / "roi.toml").write_text('roi = [[0, 0], [0.5, 0], [0.5, 1], [0, 1]]\n'
                                       'roi_units = "fraction"\n')
    assert main(["track", str(clip), "--out", str(tmp_path / "run"), "--quiet",
                 "--config", str(tmp_path / "roi.toml"), "--save-detections"]) == 0
    rows = read_mot(tmp_path / "run" / "tracks.csv")
    detected = np.loadtxt(tmp_path / "run" / "detections.csv", delimiter=",", ndmin=2)
    print(f"{len(np.unique(rows[:, 1]))} tracks; rightmost detected box edge "
          f"{(detected[:, 2] + detected[:, 4]).max():.1f} px")
    assert len(np.unique(rows[:, 1])) >= 3
    assert (detected[:, 2] + detected[:, 4]).max() <= 320 + 2


def test_calibration_named_in_the_config_is_used_and_the_option_overrides_it(
        synth_video, overhead_truth, tmp_path, capsys):
    clip = synth_video(0) / "video.avi"
    site = tmp_path / "site"
    overhead_truth(0, site)
    (site / "cfg.toml").write_text('calibration = "calibration.toml"\n')
    cwd = os.getcwd()
    os.chdir(tmp_path)   # the path is relative to the config file, not to the working folder
    try:
        assert main(["track", str(clip), "--out", "run", "--quiet", "--max-frames", "60",
                     "--config", "site/cfg.toml"]) == 0
        summary = json.loads(Path("run/summary.json").read_text())
        (tmp_path / "bad.toml").write_text("[[points]]\nimage = [0, 0]\nworld = [0, 0]\n")
        assert main(["track", str(clip), "--out", "run2", "--quiet", "--max-frames", "5",
                     "--config", "site/cfg.toml", "--calibration", "bad.toml"]) == 2
    finally:
        os.chdir(cwd)
    assert summary["calibration"] is not None and summary["calibration"]["points"] == 4
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: bad.toml")
