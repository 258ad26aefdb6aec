"""`vtrack eval` on the command line: text, --json and bad input."""

from __future__ import annotations

import json

import pytest

from vtrack.cli import main

GT = "".join(f"{f},1,{10 + f},20,30,15,1,-1,-1,-1,1\n" for f in range(1, 11))


@pytest.fixture
def files(tmp_path):
    gt, tracks = tmp_path / "gt.csv", tmp_path / "tracks.csv"
    gt.write_text(GT)
    tracks.write_text("".join(line.rsplit(",", 1)[0] + "\n" for line in GT.splitlines()))
    return gt, tracks


def test_json_stdout_is_one_json_object(files, capsys):
    assert main(["eval", str(files[0]), str(files[1]), "--json"]) == 0
    out = capsys.readouterr().out
    scores = json.loads(out)
    assert {"mota", "idf1", "hota", "id_switches", "false_positives", "misses"} <= set(scores)
    assert scores["mota"] == scores["idf1"] == scores["hota"] == 1.0


def test_text_output_names_every_metric(files, capsys):
    assert main(["eval", str(files[0]), str(files[1])]) == 0
    out = capsys.readouterr().out
    for label in ("MOTA", "IDF1", "HOTA", "ID switches", "False positives", "Misses"):
        assert label in out


def test_empty_tracks_file_is_valid(files, capsys):
    files[1].write_text("")
    assert main(["eval", str(files[0]), str(files[1]), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["misses"] == 10


@pytest.mark.parametrize("broken, text", [
    ("tracks", "1,1,0,0,10,10,1,-1,-1,-1\n2,1,0,0,ten,10,1,-1,-1,-1\n"),
    ("tracks", "1,1,0,0,10,10\n"),
    ("gt", ""),
    ("gt", None),
])
def test_bad_input_exits_2_with_one_error_line(files, capsys, broken, text):
    path = files[0] if broken == "gt" else files[1]
    if text is None:
        path.unlink()
    else:
        path.write_text(text)
    assert main(["eval", str(files[0]), str(files[1]), "--json"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == ""
    assert len(err) == 1 and err[0].startswith("error: ") and str(path) in err[0]
