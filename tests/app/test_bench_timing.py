"""scripts/bench_pipeline.py's timing: the CPU of the decoder children is counted with the
run's own, so the bound it prints on the ratio (N cores x decode-only time / CPU) covers all
of the work."""

import subprocess
import sys


def test_timed_counts_the_cpu_of_finished_children(load_script):
    bench = load_script("bench_pipeline")
    burn = [sys.executable, "-c", "sum(i * i for i in range(3_000_000))"]
    with_child = bench._timed(lambda: subprocess.run(burn, check=True))
    alone = bench._timed(lambda: sum(i * i for i in range(3_000_000)))
    assert with_child.cpu_children > with_child.cpu_self
    assert alone.cpu_self > alone.cpu_children
    assert (with_child - alone).wall == with_child.wall - alone.wall


def test_decode_only_reads_in_a_child(load_script, tmp_path):
    """A decode-only run's CPU is mostly the decoder child's, not this process's."""
    from vtrack.sim.traffic import render_scene

    bench = load_script("bench_pipeline")
    render_scene(tmp_path, frames=40, vehicles=3, width=320, height=240, fps=25.0, seed=0)
    t = bench._decode(tmp_path / "video.avi", 40)
    assert t.cpu_children > t.cpu_self > 0.0
