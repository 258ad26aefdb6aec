#!/usr/bin/env python
"""Compare `vtrack experiment NAME --json --runs 4 --seed 1` of every experiment with the
outputs recorded before the estimation refactor (tests/golden/experiments_full, see
tests/golden/record_golden.py), within the golden tests' tolerance (tests/golden/
tolerance.py). Prints one line per experiment; exit 1 if anything recorded changed (new
keys are allowed). Takes ~2 minutes; the test suite checks shrunk versions.

    .venv/bin/python tests/golden/check_outputs.py [NAME ...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

GOLDEN = Path(__file__).resolve().parent
sys.path.insert(0, str(GOLDEN))
import record_golden as rg  # noqa: E402
from tolerance import json_differences  # noqa: E402


def main() -> int:
    names = sys.argv[1:] or sorted(rg.SHRINK)
    bad = 0
    for name in names:
        want = json.loads((GOLDEN / "experiments_full" / f"{name}.json").read_text())
        diff = json_differences(want, rg.experiment_json(name, 4, 1))
        print(f"{name}: {'unchanged' if not diff else f'{len(diff)} differences'}")
        for line in diff[:10]:
            print("   ", line)
        bad += bool(diff)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
