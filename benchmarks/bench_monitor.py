"""Does the live monitor disturb the output loop? Output tick lateness with and without clients, same run.

The loop is `bench_realtime.py`'s: the real `Rig.run_trajectory` at 100 Hz in real time, writing through
the real `Usb3105` driver and pyusb to the fake USB-3105 while the real `Usb1608FsPlus` driver scans two
channels at 1 kHz, read every 10 ticks. Variants, interleaved repeat by repeat so that the machine's load
hits them alike:

- no monitor (`Rig.tap` is None: the loop of every run without --monitor);
- monitor serving with the loop's tap publishing ~20 Hz samples, no client;
- the same with 1 client reading `/events` (a separate process, as a browser is);
- the same with 16 clients (the connection cap), each in its own process.

Reported per variant: tick lateness p50 / p99 / max (median over the repeats), the messages the clients
received (they were connected and served), and the tap's own cost per scan read (median µs).

Run: python benchmarks/bench_monitor.py [--seconds 10] [--repeats 3] [--fifo]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the fake boards live in tests/fakeusb

from tests.fakeusb.backend import FakeBackend  # noqa: E402
from tests.fakeusb.usb1608fs import make_usb1608fs  # noqa: E402
from tests.fakeusb.usb3105 import make_usb3105  # noqa: E402

from bench_realtime import SPIN_S, knee_joint, sensor, summarise  # noqa: E402
from protocol_runner.hardware.interfaces import ScanBlock  # noqa: E402
from protocol_runner.hardware.rig import Rig  # noqa: E402
from protocol_runner.hardware.usb1608fs import Usb1608FsPlus  # noqa: E402
from protocol_runner.hardware.usb3105 import Usb3105  # noqa: E402
from protocol_runner.hardware.usb_common import MonotonicClock, realtime_priority  # noqa: E402
from protocol_runner.monitor.live import SampleTap  # noqa: E402
from protocol_runner.monitor.service import Monitor  # noqa: E402

FIFO = False  # --fifo: the loop under SCHED_FIFO, as the hardware bench runs it (when allowed)

READER = r"""
import socket, sys
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])))
s.sendall(b"GET /events HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
n, tail = 0, b""
while chunk := s.recv(65536):
    data = tail + chunk
    n += data.count(b"data: ")
    tail = data[-5:]
print(n)
"""


def one_trial(seconds: float, monitor: Monitor | None) -> np.ndarray:
    ao_model = make_usb3105()
    ao_model.keep_transfer_log = False
    ai_model = make_usb1608fs(signal=sensor, clock=time.monotonic)
    ai_model.keep_transfer_log = False
    backend = FakeBackend(ao_model, ai_model)
    clock = MonotonicClock(spin_s=SPIN_S)
    ao = Usb3105.open(backend=backend)
    ai = Usb1608FsPlus.open(backend=backend, clock=clock)
    try:
        rig = Rig([knee_joint()], ao, ai, clock)
        if monitor is not None:
            tap = SampleTap((rig.joint,), monitor.bus.publish_samples)
            tap.step = "bench"
            rig.tap = tap
        if FIFO:
            rig.loop_context = realtime_priority  # as the hardware bench runs it
        t = np.arange(round(seconds * 100.0)) / 100.0
        command = 65.0 + 40.0 * np.sin(2 * np.pi * t / 8.17)
        return rig.run_trajectory([command], where="bench")[0].tick_lateness_s
    finally:
        ao.close()
        ai.close()


def watched_trial(seconds: float, n_clients: int | None) -> tuple[np.ndarray, int]:
    """One trial; n_clients None = no monitor at all. Returns the lateness and the messages received."""
    if n_clients is None:
        return one_trial(seconds, None), 0
    with Monitor.open("127.0.0.1:0", say=lambda text: None) as live:
        readers = [
            subprocess.Popen(
                [sys.executable, "-c", READER, str(live.port)], stdout=subprocess.PIPE, text=True
            )
            for _ in range(n_clients)
        ]
        deadline = time.monotonic() + 20
        while live.bus.n_clients < n_clients and time.monotonic() < deadline:
            time.sleep(0.05)
        if live.bus.n_clients < n_clients:
            raise RuntimeError(f"only {live.bus.n_clients} of {n_clients} clients connected")
        lateness = one_trial(seconds, live)
    received = sum(int(r.communicate(timeout=30)[0] or 0) for r in readers)
    return lateness, received


def tap_cost_us(n: int = 2000) -> float:
    """Median µs of one SampleTap.scan on a 100-row block (what the loop pays per read with a monitor)."""
    joint = knee_joint()
    tap = SampleTap((joint,), lambda msg: None)
    tap.start("bench", np.full(1000, 65.0), 0.0)
    times = []
    for k in range(n):
        t = k * 0.1 + np.arange(100) / 1000.0
        volts = np.column_stack((np.sin(t), np.full(100, 0.5)))
        block = ScanBlock(t_s=t, codes=np.zeros((100, 2), np.int32), volts=volts)
        t0 = time.perf_counter()
        tap.scan(block)
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0, help="trial length (default 10 s)")
    parser.add_argument("--repeats", type=int, default=3, help="trials per variant (default 3)")
    parser.add_argument("--fifo", action="store_true", help="run the loop under SCHED_FIFO (hardware bench)")
    args = parser.parse_args()
    global FIFO
    FIFO = args.fifo
    if FIFO:
        with realtime_priority() as granted:
            print(f"  SCHED_FIFO for the loop: {'granted' if granted else 'refused (normal priority)'}")

    print(f"Rig.run_trajectory at 100 Hz in real time, {args.seconds:g} s trials, {args.repeats} repeats")
    print(f"  machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} (1 min) at start")
    variants: dict[str, int | None] = {
        "no monitor": None,
        "monitor, no client": 0,
        "monitor, 1 client": 1,
        "monitor, 16 clients": 16,
    }
    results: dict[str, list[tuple[float, float, float, int]]] = {label: [] for label in variants}
    for r in range(args.repeats):
        for label, clients in variants.items():
            lateness, received = watched_trial(args.seconds, clients)
            p50, p99, worst = summarise(lateness)
            results[label].append((p50, p99, worst, received))
            print(
                f"  run {r + 1}, {label}: p50 {p50:.3f} ms, p99 {p99:.3f} ms, max {worst:.3f} ms"
                + (f"; clients received {received} messages" if clients else "")
            )
    print()
    print(f"Median over {args.repeats} runs (tick lateness = write time - scheduled time):")
    for label, rows in results.items():
        p50 = statistics.median(x[0] for x in rows)
        p99 = statistics.median(x[1] for x in rows)
        worst = statistics.median(x[2] for x in rows)
        verdict = "meets" if p99 < 1.0 else "MISSES"
        print(f"  {label}: p50 {p50:.3f} ms, p99 {p99:.3f} ms, max {worst:.3f} ms ({verdict} p99 < 1 ms)")
    print(f"  SampleTap.scan per read (100 rows -> 2 points): median {tap_cost_us():.1f} µs")
    print(f"  load average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
