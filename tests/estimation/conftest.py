"""Make the plain helper module `seed000` importable from these tests under any pytest
import mode (it is not a test module and not part of the package)."""

import sys
from pathlib import Path

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)
