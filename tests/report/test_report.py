"""vtrack report: the page's sections, charts and first frame, its tables equal to the CSVs,
no network references, bad run folders, and a real headless browser rendering it."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
from collections import defaultdict
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from vtrack.analytics.vehicles import CLASS_ORDER
from vtrack.cli import main
from vtrack.vision.appearance import VEHICLE_CLASSES

CHROMIUM = Path("/usr/bin/chromium")
CONFIG = """\
count_lines = [{name = "west", points = [[0.25, 0.25], [0.25, 0.8]], units = "fraction"},
               [480, 90, 480, 290]]
[[zones]]
name = "bay"
polygon = [[0.35, 0.62], [0.55, 0.62], [0.55, 0.74], [0.35, 0.74]]
units = "fraction"
[[gates]]
name = "left"
line = [[0.1, 0.0], [0.1, 1.0]]
units = "fraction"
[[gates]]
name = "right"
polygon = [[0.88, 0.0], [1.0, 0.0], [1.0, 1.0], [0.88, 1.0]]
units = "fraction"
"""


class Page(HTMLParser):
    """Sections (by id), tables (by class: rows of cell texts), svg/image elements and every
    src/href attribute."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.sections: list[str] = []
        self.tables: dict[str, list[list[str]]] = {}
        self.svgs = 0
        self.images: list[str] = []
        self.links: list[str] = []
        self.text: list[str] = []
        self._table: str | None = None
        self._cell: list[str] | None = None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "section":
            self.sections.append(a.get("id", ""))
        elif tag == "table":
            self._table = a.get("class", "")
            self.tables[self._table] = []
        elif tag == "tr" and self._table is not None:
            self.tables[self._table].append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "svg":
            self.svgs += 1
        elif tag in ("image", "img"):
            self.images.append(a.get("href") or a.get("src") or "")
        for k in ("src", "href"):
            if k in a:
                self.links.append(a[k])

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None and self._table is not None:
            self.tables[self._table][-1].append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def calibrated_run(synth_video, overhead_truth, tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    cfg = out / "cfg.toml"
    cfg.write_text(CONFIG)
    calib = overhead_truth(0, tmp_path_factory.mktemp("truth"))
    assert main(["track", str(synth_video(0) / "video.avi"), "--out", str(out / "r"),
                 "--quiet", "--config", str(cfg), "--calibration", str(calib),
                 "--bin-seconds", "2", "--save-frames"]) == 0
    return out / "r"


def test_page_sections_charts_and_tables_equal_the_csvs(calibrated_run, cli_stdout):
    run = calibrated_run
    assert cli_stdout(["report", str(run)]).strip() == str(run / "report.html")
    page = Page((run / "report.html").read_text())
    assert page.sections == ["counts", "p85", "speeds", "movements", "map", "zones"]
    speeds = [r for r in _rows(run / "speeds.csv") if r["class"] == "all"]
    p85_charts = len({(r["line"], r["direction"]) for r in speeds if r["p85_kmh"]})
    # 2 lines x 2 directions, p85 per line and direction with speeds, speeds, map
    assert page.svgs == 4 + p85_charts + 1 + 1 and p85_charts >= 2
    assert len(page.images) == 1 and page.images[0].startswith("data:image/jpeg;base64,")
    assert all(link.startswith("data:") for link in page.links), "no network references"
    text = " ".join(page.text)
    assert "frames/000001.jpg" in text

    counts = _rows(run / "counts.csv")
    table = page.tables["counts-table"]
    classes = table[0][2:-1]
    # the default (hybrid) detector: the length's classes and the appearance model's
    assert [c for c in classes if c != "unknown"] == list(CLASS_ORDER)
    expect = defaultdict(int)
    for r in counts:
        expect[(r["line"], r["direction"], r["class"])] += int(r["count"])
    for row in table[1:]:
        line, direction, *cells, total = row
        assert [int(c) for c in cells] == [expect[(line, direction, c)] for c in classes]
        assert int(total) == sum(expect[(line, direction, c)] for c in classes)
    assert {(r[0], r[1]) for r in table[1:]} == {("west", "forward"), ("west", "backward"),
                                                 ("1", "forward"), ("1", "backward")}

    vehicles = _rows(run / "vehicles.csv")
    speed = {r[0]: r for r in page.tables["speed-table"][1:]}
    for cls, row in speed.items():
        mine = [v for v in vehicles if v["class"] == cls]
        sp = [float(v["speed_mean_kmh"]) for v in mine]
        assert int(row[1]) == len(mine)
        assert float(row[2]) == pytest.approx(np.mean(sp), abs=0.05)
        assert float(row[3]) == pytest.approx(np.percentile(sp, 85), abs=0.05)
        assert float(row[4]) == pytest.approx(max(float(v["speed_max_kmh"]) for v in mine),
                                              abs=0.05)
    assert sum(int(r[1]) for r in speed.values()) == len(vehicles)

    table = page.tables["p85-table"][1:]
    assert [[r[1], r[2], r[3], r[6]] for r in table] == [
        [r["line"], r["direction"], r["count"], r["p85_kmh"]] for r in speeds if int(r["count"])]

    summary = json.loads((run / "summary.json").read_text())
    od = page.tables["od-table"]
    assert od[0] == ["from \\ to", "left", "right", "total out"]
    moves = {(m["from"], m["to"]): m["count"] for m in summary["movements"]}
    assert od[1][1:3] == ["–", str(moves[("left", "right")])]
    assert od[2][1:3] == [str(moves[("right", "left")]), "–"]
    assert moves[("left", "right")] + moves[("right", "left")] > 0
    binned = defaultdict(int)
    for r in _rows(run / "movements.csv"):
        binned[(r["from"], r["to"])] += int(r["count"])
    assert dict(binned) == moves
    events = _rows(run / "zone_events.csv")
    (zone_row,) = page.tables["zone-table"][1:]
    z = summary["zones"][0]
    assert zone_row[:3] == ["bay", str(z["entries"]), str(z["max_occupancy"])]
    assert int(zone_row[1]) == len(events) > 0
    assert float(zone_row[3]) == pytest.approx(
        np.mean([float(e["dwell_s"]) for e in events]), abs=0.01)


def test_first_frame_from_the_video_or_a_blank_canvas(synth_video, tmp_path, cli_stdout):
    video = tmp_path / "clip.avi"
    shutil.copy(synth_video(1) / "video.avi", video)
    run = tmp_path / "run"
    assert main(["track", str(video), "--out", str(run), "--quiet", "--max-frames", "120",
                 "--count-line", "50%,0%,50%,100%"]) == 0
    cli_stdout(["report", str(run), "--quiet"])
    page = Page((run / "report.html").read_text())
    assert page.sections == ["counts", "p85", "speeds", "movements", "map", "zones"]
    assert len(page.images) == 1 and "first frame of clip.avi" in " ".join(page.text)
    assert "no calibration" in " ".join(page.text)              # speeds section explains
    assert "No speeds at the lines: the run has no calibration" in " ".join(page.text)
    assert "two or more gates" in " ".join(page.text)
    # no calibration: the default (hybrid) detector's appearance classes
    assert [c for c in page.tables["counts-table"][0][2:-1]
            if c != "unknown"] == [c for c in CLASS_ORDER if c in VEHICLE_CLASSES]
    video.unlink()
    cli_stdout(["report", str(run), "--quiet"])
    page = Page((run / "report.html").read_text())
    assert page.images == [] and "blank canvas" in " ".join(page.text)


def test_a_folder_that_is_not_a_run_exits_2(tmp_path, capsys):
    cases = [tmp_path / "missing", tmp_path / "empty", tmp_path / "badjson"]
    cases[1].mkdir()
    cases[2].mkdir()
    (cases[2] / "summary.json").write_text("{not json")
    (cases[2] / "tracks.csv").write_text("")
    for d, what in zip(cases, ["not a folder", "no summary.json", "malformed JSON"]):
        assert main(["report", str(d)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ") and what in err[0], err
        assert not (d / "report.html").exists()


@pytest.mark.skipif(not CHROMIUM.exists(), reason="no headless browser (apt-get install chromium)")
def test_page_renders_in_a_headless_browser(calibrated_run, tmp_path):
    import cv2

    main(["report", str(calibrated_run), "--quiet"])
    shot = tmp_path / "report.png"
    proc = subprocess.run(
        [str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
         "--window-size=1200,3400", (calibrated_run / "report.html").as_uri()],
        capture_output=True, timeout=120)
    assert proc.returncode == 0, proc.stderr.decode()[-500:]
    img = cv2.imread(str(shot))
    assert img is not None and img.shape[:2] == (3400, 1200)
    # the page drew charts and the frame: many distinct colours, not a blank or error page
    colours = np.unique((img[::4, ::4] // 32).reshape(-1, 3), axis=0)
    assert len(colours) > 40
    # the class colours of the bars are on the page (car blue #2f80ed is BGR 237,128,47)
    near_blue = np.all(np.abs(img.astype(int) - (237, 128, 47)) < 12, axis=2)
    assert near_blue.sum() > 500
