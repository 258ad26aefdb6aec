"""TrafficAnalytics on a long stream: periodic flushes only append, finished tracks are
evicted (memory stays flat), and the files end equal to a run flushed once at the end."""

from __future__ import annotations

from collections import Counter

from test_zones import _frame

from vtrack.analytics.regions import CountLine, Gate, Zone
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
                          bin_seconds=10.0, bin_settle_s=5.0,
                          gates=[Gate("w", line=((102, 0), (102, 360))),
                                 Gate("e", line=((538, 0), (538, 360))),
                                 Gate("mid", polygon=((302, 0), (338, 0), (338, 360), (302, 360)))])
    an.flush()
    snapshots, live = [], []
    for n in range(1, frames + 1):
        an.add_frame(n, (n - 1) / FPS, _frame(n, _stream(n)))
        if flush_every and n % flush_every == 0:
            an.flush()
            snapshots.append({name: (out / name).read_bytes() for name in HEADERS})
            live.append((len(an.vehicles), len(an.counter._last), len(an.zones._state),
                         max(len(an.bins._open), len(an.movement_bins._open)),
                         len(an.gates._passes)))
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
    assert max(v[0] for v in live) <= 9 and max(v[4] for v in live) <= 9
    assert max(v[1] for v in live) <= 9 and max(v[2] for v in live) <= 9
    assert max(v[3] for v in live) <= 2
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

    # every vehicle crosses both line gates and the polygon: the first gate to the last
    moves = {(m["from"], m["to"]): m["count"] for m in an.summary()["movements"]}
    rows = [line.split(",") for line in
            (tmp_path / "live/movements.csv").read_text().splitlines()[1:]]
    for (a, b), n in moves.items():
        assert sum(int(r[5]) for r in rows if (r[2], r[3]) == (a, b)) == n
    passes: dict[int, dict[str, int]] = {}          # track -> gate -> first frame passed
    for n in range(1, frames + 1):
        for tid, (x, _, w, _) in _stream(n).items():
            c, p = x + w / 2, passes.setdefault(tid, {"x": [], "at": {}})
            p["x"].append(c)
            for gate, x0 in (("w", 102), ("e", 538)):
                if len(p["x"]) > 1 and (p["x"][-2] - x0) * (c - x0) < 0:
                    p["at"].setdefault(gate, n)
            if 302 < c < 338:
                p["at"].setdefault("mid", n)
    expect = Counter()
    for p in passes.values():
        order = sorted(p["at"], key=p["at"].get)
        if len(order) > 1:
            expect[(order[0], order[-1])] += 1
    assert +Counter(moves) == expect and expect[("w", "e")] > 120 and expect[("e", "w")] > 120
