"""Make tests/golden importable here (record_golden: the outputs recorded before the
estimation refactor, which the experiment JSON tests compare with)."""

import sys
from pathlib import Path

_GOLDEN = str(Path(__file__).resolve().parents[1] / "golden")
if _GOLDEN not in sys.path:
    sys.path.insert(0, _GOLDEN)
