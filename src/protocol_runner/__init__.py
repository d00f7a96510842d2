"""protocol-runner: a declarative test-protocol runner for space-suit joint testing on the RSST robot.

Data flow: protocol (YAML) -> plan (ordered steps) -> session (runs steps against a rig) -> archive (HDF5)
-> analysis (processing and model fits) -> report (HTML).
"""

# BLAS threads: the model fits hold BLAS at one thread while they run (threadpoolctl,
# models/bouc_wen/threads.py), whenever numpy was imported; nothing is set here at import time.
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("protocol-runner")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+source"

__all__ = ["__version__"]
