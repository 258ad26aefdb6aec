"""`vtrack setup` in a real headless Chromium (Debian's chromium + chromium-driver, driven by
selenium): lines, gates, a zone, the region of interest and six calibration points on three
lane lines (collinear triples) are drawn by clicks on the first frame of a synthetic mast
scene, named, saved, and the saved config is run with `vtrack track --config`."""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from vtrack.analytics.calibration import load_calibration, parse_calibration
from vtrack.cli import main
from vtrack.errors import InputError
from vtrack.fileio import read_toml

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome"))
                 if p), None)
CHROMEDRIVER = shutil.which("chromedriver")

# Road-plane metres of the mast scene (seed 1): X along the road, Y across it.
LANE_POINTS = [(15.0, -3.5), (40.0, -3.5), (15.0, 0.0), (40.0, 0.0), (15.0, 3.5), (40.0, 3.5)]
LINES = {"near": [(15.0, -11.0), (15.0, 11.0)], "far": [(25.0, -11.0), (25.0, 11.0)]}
GATE_LINE = [(11.0, -11.0), (11.0, 11.0)]
GATE_POLYGON = [(30.0, -11.0), (34.0, -11.0), (34.0, 11.0), (30.0, 11.0)]
ZONE = [(18.0, -10.0), (22.0, -10.0), (22.0, 0.0), (18.0, 0.0)]
ROI = [(8.0, -13.0), (70.0, -13.0), (70.0, 13.0), (8.0, 13.0)]


def _browser():
    """A headless Chromium under selenium, or a skip naming what is missing."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.skip("selenium is not installed (pip install -e '.[test]')")
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip("no Chromium with chromedriver on PATH (Debian: apt-get install chromium "
                    "chromium-driver; scripts/setup_env.sh does it when run as root)")
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1400,900", "--no-first-run", "--disable-extensions"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(executable_path=CHROMEDRIVER), options=opts)


@pytest.fixture(scope="module")
def mast(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("mast")
    assert main(["synth", str(out), "--scene", "mast", "--frames", "250", "--seed", "1"]) == 0
    return out


def _start_setup(video: Path) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen([sys.executable, "-m", "vtrack", "setup", str(video),
                             "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    line = proc.stdout.readline()
    match = re.search(r"http://127\.0\.0\.1:\d+/", line)
    if not match:
        proc.kill()
        pytest.fail(f"no address on the first line: {line!r} {proc.stderr.read()!r}")
    return proc, match[0]


class Page:
    """Clicks on the canvas at image pixels (the canvas may be shown scaled)."""

    def __init__(self, driver, width: int, height: int) -> None:
        from selenium.webdriver.common.by import By

        self.d, self.By = driver, By
        self.size = (width, height)

    def find(self, css: str):
        return self.d.find_element(self.By.CSS_SELECTOR, css)

    def click_image(self, u: float, v: float) -> tuple[float, float]:
        """Click the canvas pixel nearest (u, v); returns the image point the page gets."""
        from selenium.webdriver.common.actions.action_builder import ActionBuilder

        r = self.d.execute_script(
            "const r = document.getElementById('canvas').getBoundingClientRect();"
            "return [r.left, r.top, r.width, r.height];")
        sx, sy = r[2] / self.size[0], r[3] / self.size[1]
        x, y = round(r[0] + u * sx), round(r[1] + v * sy)
        ab = ActionBuilder(self.d)
        ab.pointer_action.move_to_location(x, y)
        ab.pointer_action.click()
        ab.perform()
        time.sleep(0.05)
        return (x - r[0]) / sx, (y - r[1]) / sy

    def tool(self, name: str) -> None:
        self.find(f"#tool-{name}").click()

    def name(self, kind: str, index: int, text: str) -> None:
        box = self.find(f"#name-{kind}-{index}")
        box.clear()
        box.send_keys(text)


def _image(cal, world: list[tuple[float, float]], size: tuple[int, int]) -> np.ndarray:
    pts = cal.to_image(np.array(world, float))
    return np.clip(pts, 2, np.array(size) - 3)


def test_draw_save_and_track(mast, tmp_path):
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import WebDriverWait

    truth = load_calibration(mast / "calibration.toml")
    size = (640, 360)
    driver = _browser()
    proc, url = _start_setup(mast / "video.avi")
    try:
        driver.get(url)
        WebDriverWait(driver, 20).until(
            lambda d: d.execute_script("return document.body.dataset.ready") == "yes")
        page = Page(driver, *size)
        for k, (name, ends) in enumerate(LINES.items()):
            page.tool("line")
            for u, v in _image(truth, ends, size):
                page.click_image(u, v)
            page.name("line", k, name)
        page.find("#rev-line-1").click()                     # "far" counts the other way
        page.tool("gate-line")
        for u, v in _image(truth, GATE_LINE, size):
            page.click_image(u, v)
        page.name("gate", 0, "south")
        page.tool("gate-polygon")
        for u, v in _image(truth, GATE_POLYGON, size):
            page.click_image(u, v)
        page.find("body").send_keys(Keys.ENTER)            # closes the polygon
        page.name("gate", 1, "north")
        page.tool("zone")
        zone = _image(truth, ZONE, size)
        for u, v in zone:
            page.click_image(u, v)
        page.click_image(*zone[0])                           # the first vertex closes it
        page.name("zone", 0, "queue")
        page.tool("roi")
        for u, v in _image(truth, ROI, size):
            page.click_image(u, v)
        page.find("#finish").click()
        page.tool("point")
        clicked = []
        for k, (X, Y) in enumerate(LANE_POINTS):
            clicked.append(page.click_image(*truth.to_image(np.array([X, Y]))))
            page.find(f"#X-{k}").send_keys(f"{X:g}")
            page.find(f"#Y-{k}").send_keys(f"{Y:g}")
        WebDriverWait(driver, 10).until(
            lambda d: d.find_element(page.By.ID, "fit").get_attribute("data-points") == "6"
            and d.find_element(page.By.ID, "fit").get_attribute("data-state") != "none")
        fit_state = page.find("#fit").get_attribute("data-state")
        fit_text = page.find("#fit").text
        shot = tmp_path / "setup_page.png"
        driver.save_screenshot(str(shot))
        print(f"screenshot {shot}; fit on the page: {fit_text}")
        page.find("#save").click()
        WebDriverWait(driver, 10).until(
            lambda d: d.find_element(page.By.ID, "status").text.startswith(("Saved", "Not")))
        status = page.find("#status").text
        assert status.startswith("Saved"), status
        page.find("#done").click()
        assert proc.wait(timeout=10) == 0
        assert proc.stderr.read() == ""
        # A second session shows what was saved, ready to edit.
        proc, url = _start_setup(mast / "video.avi")
        driver.get(url)
        WebDriverWait(driver, 20).until(
            lambda d: d.execute_script("return document.body.dataset.ready") == "yes")
        shown = driver.execute_script(
            "return [...document.querySelectorAll('#panel input')].map(e => e.id + '=' + e.value)")
        assert {"name-line-0=near", "name-line-1=far", "name-gate-0=south",
                "name-gate-1=north", "name-zone-0=queue", "X-5=40", "Y-5=3.5"} <= set(shown)
        WebDriverWait(driver, 10).until(
            lambda d: d.find_element(page.By.ID, "fit").get_attribute("data-state") == fit_state)
        page.find("#done").click()
        assert proc.wait(timeout=10) == 0
    finally:
        driver.quit()
        if proc.poll() is None:
            proc.kill()
            proc.wait()

    cfg_path = mast / "video.toml"
    saved = read_toml(cfg_path)
    assert [l["name"] for l in saved["count_lines"]] == ["near", "far"]
    assert [g["name"] for g in saved["gates"]] == ["south", "north"]
    assert "line" in saved["gates"][0] and len(saved["gates"][1]["polygon"]) == 4
    assert saved["zones"][0]["name"] == "queue" and len(saved["zones"][0]["polygon"]) == 4
    assert len(saved["roi"]) == 4 and saved["roi_units"] == "px"
    assert saved["calibration"] == "video.calibration.toml"
    cal_toml = read_toml(mast / "video.calibration.toml")
    assert cal_toml["frame_size"] == [640, 360]
    assert [tuple(p["world"]) for p in cal_toml["points"]] == LANE_POINTS
    assert np.allclose([p["image"] for p in cal_toml["points"]], clicked, atol=0.06)
    # The ends are saved in the order clicked (Y = -11, on the right, first): the order
    # that fixes the forward direction the page's arrow shows.
    (x1, _), (x2, _) = saved["count_lines"][0]["points"]
    assert x1 > x2
    (x1, _), (x2, _) = saved["count_lines"][1]["points"]     # reversed on the page
    assert x1 < x2

    # Collinear triples along lane lines are allowed: the page showed the project's own fit.
    fitted = parse_calibration(cal_toml, "calibration")
    assert fit_state == "ok", fit_text
    print(f"fit accepted: {fitted.errors()}")

    out = tmp_path / "run"
    assert main(["config", "--check", str(cfg_path)]) == 0
    assert main(["track", str(mast / "video.avi"), "--out", str(out), "--quiet",
                 "--config", str(cfg_path)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    counts = {c["name"]: c for c in summary["counts"]}
    print(f"counts {[(n, c['forward'], c['backward']) for n, c in counts.items()]}, "
          f"zones {summary['zones']}, calibration {summary['calibration']}")
    assert set(counts) == {"near", "far"}
    assert all(c["total"] > 0 for c in counts.values())
    assert summary["zones"][0]["name"] == "queue"
    assert summary["calibration"] is not None
    with open(out / "counts.csv", newline="") as fh:
        lines_in_csv = {row["line"] for row in csv.DictReader(fh)}
    assert lines_in_csv == {"near", "far"}
    with open(out / "movements.csv", newline="") as fh:
        pairs = {(r["from"], r["to"]) for r in csv.DictReader(fh)}
    assert pairs == {("south", "north"), ("north", "south")}
