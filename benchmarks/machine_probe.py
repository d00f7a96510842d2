"""The machine's own speed, apart from this project's code: fixed workloads timed the same way in every sitting.

    python benchmarks/machine_probe.py [--repeats 5]

The shared 2-core machine's speed has moved by 10-25 % between sittings and by 3.0-3.4x between the
machines sessions were given (docs/simulator.md), so a dry run's time alone cannot say
whether the code or the machine changed. `bench_dry_run.py` prints these figures before and after its runs;
compare them with those recorded beside earlier measurements. Each figure is the median of `repeats` runs
of a workload that depends only on CPython, numpy and zlib (no file system, no threads):

- python_loop_s: 2,000,000 iterations of integer and float arithmetic in the interpreter (the per-call
  Python of the session, the solver's iterations, the figures' artists);
- numpy_s: sorting 1,000,000 seeded float64 values, 20 reductions and 20 elementwise products of them
  (the processing's array work);
- zlib_s: deflating 8 MB of seeded random bytes of 16 distinct values at level 1 (the archive's compression).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import zlib

import numpy as np


def _python_loop() -> float:
    acc, x = 0, 0.5
    for i in range(2_000_000):
        acc += i & 7
        x = x * 0.999 + 0.001
    return acc + x


def _numpy() -> float:
    values = np.random.default_rng(20).standard_normal(1_000_000)
    out = float(np.sort(values)[500_000])
    for _ in range(20):
        out += float(np.sum(values * values))
    return out


_BYTES = (np.random.default_rng(21).integers(0, 16, 8 * 2**20, dtype=np.uint8) * 3).tobytes()


def _zlib() -> float:
    return float(len(zlib.compress(_BYTES, 1)))


def probe_s(repeats: int = 3) -> dict[str, float]:
    """Median wall seconds of each workload over `repeats` runs (one warm-up run first)."""
    result: dict[str, float] = {}
    for name, work in (("python_loop_s", _python_loop), ("numpy_s", _numpy), ("zlib_s", _zlib)):
        work()
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            work()
            times.append(time.perf_counter() - t0)
        result[name] = round(statistics.median(times), 3)
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    print(json.dumps(probe_s(args.repeats), indent=2))


if __name__ == "__main__":
    main()
