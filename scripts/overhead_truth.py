"""World ground truth of an overhead `vtrack synth` clip, for scripts/eval_speed.py.

`vtrack synth` writes world.csv only for the perspective scenes (INTERFACE.md); the overhead
scene is a pure scale, so its truth follows from the same seed and settings:

    vtrack synth /tmp/demo --seed 3 --frames 1500 --vehicles 60
    python scripts/overhead_truth.py /tmp/demo --seed 3 --frames 1500 --vehicles 60
    python scripts/eval_speed.py /tmp/demo /tmp/demo_run

writes DIR/world.csv (`frame,id,X_m,Y_m,speed_kmh,length_m,class`; Y from the road's top kerb).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from vtrack.fileio import write_text
from vtrack.sim.groundtruth import format_world
from vtrack.sim.traffic import simulate_traffic, world_rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", type=Path, help="the clip's folder (world.csv is written there)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--vehicles", type=int, default=12)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--fps", type=float, default=25.0)
    a = ap.parse_args()
    traj = simulate_traffic(a.frames, a.vehicles, a.width, a.height, a.fps, a.seed)
    write_text(a.dir / "world.csv", format_world(world_rows(traj)))


if __name__ == "__main__":
    main()
