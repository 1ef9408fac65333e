"""Snapshot throughput of the app's worker bridge (pickled numpy over multiprocessing queues).

Usage: .venv/bin/python bench/bench_worker_transfer.py [N ...]   (default 10000 100000 300000)
Runs the test fake engine (no real stylization work) and counts snapshots per second arriving at a UI that
polls every 5 ms; colour-only snapshots are [N,3] float32 x 2, geometry ones add means/scales/quats/opacity.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fakes import make_fake_engine  # noqa: E402

from app.worker import WorkerBridge  # noqa: E402


def measure(n: int, seconds: float = 3.0) -> tuple[float, float]:
    """(colour snapshots per second, MB per second) for n Gaussians."""
    bridge = WorkerBridge(make_fake_engine, {"n": n, "step_seconds": 0.0})
    bridge.start()
    bridge.wait_until(lambda s: s.snapshots_received > 3, 60)
    start_count, t0 = bridge.state.snapshots_received, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        bridge.poll()
        time.sleep(0.005)
    rate = (bridge.state.snapshots_received - start_count) / (time.perf_counter() - t0)
    bridge.quit()
    return rate, rate * n * 3 * 4 * 2 / 1e6


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [10_000, 100_000, 300_000]
    print(f"{'N':>8} {'snapshots/s':>12} {'MB/s':>8}")
    rows = []
    for n in sizes:
        rate, mbps = measure(n)
        rows.append((n, rate))
        print(f"{n:>8} {rate:>12.1f} {mbps:>8.1f}")
    print("RESULT " + " ".join(f"N={n}:{r:.0f}/s" for n, r in rows))


if __name__ == "__main__":
    main()
