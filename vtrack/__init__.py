"""vtrack: vehicle tracking in traffic video on one shared estimation core."""

__version__ = "0.1.0"

import os as _os

# The core works on tiny matrices (2x2 .. 15x15), where multi-threaded BLAS only adds
# synchronisation cost (measured: solve_triangular 4 ms/call under load); one thread each.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
