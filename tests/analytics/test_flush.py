"""TrafficAnalytics on a long stream: periodic flushes only append, finished tracks are
evicted (memory stays flat), and the files end equal to a run flushed once at the end."""

from __future__ import annotations

from collections import Counter

from test_zones import _frame

from vtrack.analytics.regions import CountLine, Zone
from vtrack.analytics.traffic import HEADERS, TrafficAnalytics

FPS = 25.0


def _stream(n: int) -> dict[int, tuple]:
    """Frame n of an endless road: a vehicle enters every 10 frames and crosses the 640 px
    image in 80 frames (so 8 are in view), alternately left-to-right and right-to-left."""
    boxes = {}
    for tid in range(max(1, (n - 80) // 10), n // 10 + 1):
        age = n - 10 * tid
        if 0 <= age < 80:
            x = 8 * age if tid % 2 else 600 - 8 * age
            boxes[tid] = (x, 100 + 20 * (tid % 3), 40, 30)
    return boxes


def _run(out, frames: int, flush_every: int | None) -> tuple[TrafficAnalytics, list]:
    an = TrafficAnalytics(out, 640, 360, FPS, lines=[CountLine(((320, 0), (320, 360)))],
                          zones=[Zone("bay", ((200, 0), (400, 0), (400, 360), (200, 360)))],
                          bin_seconds=10.0, bin_settle_s=5.0)
    an.flush()
    snapshots, live = [], []
    for n in range(1, frames + 1):
        an.add_frame(n, (n - 1) / FPS, _frame(n, _stream(n)))
        if flush_every and n % flush_every == 0:
            an.flush()
            snapshots.append({name: (out / name).read_bytes() for name in HEADERS})
            live.append((len(an.vehicles), len(an.counter._last), len(an.zones._state),
                         len(an.bins._open)))
    an.flush(final=True)
    return an, snapshots, live


def test_periodic_flush_appends_and_memory_stays_flat(tmp_path):
    frames = 3000                                                 # 2 minutes
    an, snaps, live = _run(tmp_path / "live", frames, flush_every=250)
    for a, b in zip(snaps, snaps[1:]):
        for name in HEADERS:
            assert b[name].startswith(a[name]), f"{name} was rewritten, not appended"
    assert all(len(s["vehicles.csv"]) > len(snaps[0]["vehicles.csv"]) for s in snaps[2:])
    assert len(snaps[-1]["counts.csv"]) > len(snaps[2]["counts.csv"])   # settled bins
    # per-track state only for the vehicles in view, a few open bins
    assert max(v for v, _, _, _ in live) <= 9
    assert max(c for _, c, _, _ in live) <= 9 and max(z for _, _, z, _ in live) <= 9
    assert max(b for _, _, _, b in live) <= 2
    _, _, _ = _run(tmp_path / "once", frames, flush_every=None)
    for name in HEADERS:
        lines = [(tmp_path / d / name).read_text().splitlines() for d in ("live", "once")]
        assert lines[0][0] == lines[1][0] == ",".join(HEADERS[name])
        assert Counter(lines[0][1:]) == Counter(lines[1][1:]), name
    counts = [line.split(",") for line in (tmp_path / "live/counts.csv").read_text().splitlines()[1:]]
    summary = an.summary()["counts"][0]
    for d in ("forward", "backward"):
        assert sum(int(r[5]) for r in counts if r[3] == d) == summary[d]
    sides: dict[int, set] = {}
    for n in range(1, frames + 1):
        for tid, (x, _, w, _) in _stream(n).items():
            sides.setdefault(tid, set()).add(x + w / 2 > 320)
    assert summary["total"] == sum(len(v) == 2 for v in sides.values()) > 250
