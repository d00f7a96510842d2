"""protocol-runner: a declarative test-protocol runner for space-suit joint testing on the RSST robot.

Data flow: protocol (YAML) -> plan (ordered steps) -> session (runs steps against a rig) -> archive (HDF5)
-> analysis (processing and model fits) -> report (HTML).

From Python (docs/api.md): `load_protocol`, `run`, `open_archive`, `write_report`, `export` - what the
`run-protocol` command does, as functions. They import what they need when called: importing the package
loads neither numpy nor numba.
"""

# BLAS threads: the model fits hold BLAS at one thread while they run (threadpoolctl,
# models/bouc_wen/threads.py), whenever numpy was imported; nothing is set here at import time.
from importlib.metadata import PackageNotFoundError, version

from .api import export, load_protocol, open_archive, run, write_report
from .numba_cache import point_numba_at_the_user_cache

# numba reads NUMBA_CACHE_DIR once, when it is first imported: set here, before any module of the package
# can import it, so the compiled kernels are cached in the user's cache directory (numba_cache.py)
point_numba_at_the_user_cache()

try:
    __version__ = version("protocol-runner")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+source"

__all__ = ["__version__", "export", "load_protocol", "open_archive", "run", "write_report"]
