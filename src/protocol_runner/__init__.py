"""protocol-runner: a declarative test-protocol runner for space-suit joint testing on the RSST robot.

Data flow: protocol (YAML) -> plan (ordered steps) -> session (runs steps against a rig) -> archive (HDF5)
-> analysis (processing and model fits) -> report (HTML).
"""

import os

# BLAS threads hand work back and forth on the tall, thin Jacobians of the model fits; on a 2-core machine
# single-threaded BLAS is 3-10x faster there (benchmarks/bench_bouc_wen.py). Set before numpy loads; a
# user's own setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from importlib.metadata import PackageNotFoundError, version  # noqa: E402

try:
    __version__ = version("protocol-runner")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+source"

__all__ = ["__version__"]
