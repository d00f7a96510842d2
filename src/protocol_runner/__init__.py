"""protocol-runner: a declarative test-protocol runner for space-suit joint testing on the RSST robot.

Data flow: protocol (YAML) -> plan (ordered steps) -> session (runs steps against a rig) -> archive (HDF5)
-> analysis (processing and model fits) -> report (HTML).

From Python (docs/api.md): `load_protocol`, `run`, `open_archive`, `write_report`, `export` - what the
`run-protocol` command does, as functions. They import what they need when called: importing the package
loads neither numpy nor numba.
"""

from .api import export, load_protocol, open_archive, run, write_report
from .numba_cache import point_numba_at_the_user_cache

# numba reads NUMBA_CACHE_DIR once, when it is first imported: set here, before any module of the package
# can import it, so the compiled kernels are cached in the user's cache directory (numba_cache.py)
point_numba_at_the_user_cache()


def __getattr__(name: str) -> str:
    """`__version__`, read from the installed package's metadata when first asked for (importing
    `importlib.metadata` takes about 0.1 s, which `run-protocol` does not spend at start)."""
    if name != "__version__":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        value = version("protocol-runner")
    except PackageNotFoundError:  # running from a source tree that is not installed
        value = "0.0.0+source"
    globals()["__version__"] = value
    return value


__all__ = ["__version__", "export", "load_protocol", "open_archive", "run", "write_report"]
