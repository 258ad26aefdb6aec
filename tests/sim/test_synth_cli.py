"""`vtrack synth` on the command line: outputs and bad settings."""

from __future__ import annotations

import pytest

from vtrack.cli import main


def test_synth_writes_video_and_gt(tmp_path, capsys):
    out = tmp_path / "clip"
    assert main(["synth", str(out), "--frames", "12", "--vehicles", "3", "--width", "200",
                 "--height", "120", "--seed", "2"]) == 0
    assert (out / "video.avi").stat().st_size > 0
    assert (out / "gt.csv").read_text().count("\n") > 0
    assert sorted(p.name for p in out.iterdir()) == ["gt.csv", "video.avi"]
    assert "video.avi" in capsys.readouterr().out


@pytest.mark.parametrize("args", [["--frames", "0"], ["--width", "10"], ["--fps", "0"],
                                  ["--seed", "-1"], ["--vehicles", "-2"], ["--quality", "0"]])
def test_bad_settings_exit_2_with_one_error_line(tmp_path, capsys, args):
    assert main(["synth", str(tmp_path / "x"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and args[0] in err[0]
    assert not (tmp_path / "x").exists()


def test_out_dir_that_is_a_file_is_bad_input(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert main(["synth", str(target), "--frames", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(target) in err[0]
