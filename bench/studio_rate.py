"""The studio's live rate: its engine worker (a spawned process, as the studio starts it) stylizing on a device.

The worker is built exactly as the studio builds it (``app.engine_factory.make_stylizer`` behind ``WorkerBridge``:
one compute thread, a lower priority, the snapshot credits), here with ``--device`` and ``--working-width``. This
side plays the UI: it polls the bridge every ``--poll-ms`` (a 60 Hz frame) and applies what arrives. Once the
worker reports its stylize phase (its first ``--skip`` steps there not counted) it counts, over ``--seconds``:

- stylize steps a second (the reports of optimiser steps), and all steps a second (the refits between them too);
- the optimiser steps' own rate (their count over the seconds their reports give), and their rate as this side
  sees them arrive (over the intervals between two optimiser steps with no refit between them: the step, its
  snapshot and the transfer);
- snapshots a second that reached this side (what the viewer can show), and their colours' size.

``--preset final`` gives a longer stylization (the preview at 512 px ends within seconds on a GPU);
``--worker-threads`` sets the worker's torch threads (the studio's: 1).

    python bench/studio_rate.py [--device cuda] [--working-width 512] [--seconds 20] [--preset preview]

Prints the machine, then ``RESULT studio_stylize_steps_per_s=… studio_snapshots_per_s=…``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.engine_factory import make_stylizer  # noqa: E402
from app.worker import WorkerBridge  # noqa: E402
from gstyle_core.engine.phases.stylize import is_optimiser_step  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402


def optimiser_report(report: dict | None) -> bool:
    """True for a worker's report of a stylization optimiser step."""
    return bool(report) and is_optimiser_step(report.get("phase"), report.get("message"))


def measure(config: dict, seconds: float, skip: int, poll_s: float, timeout: float) -> dict:
    """Counts of the worker's steps and of the snapshots this side received, from its stylization on."""
    bridge = WorkerBridge(make_stylizer, config)
    t_start = time.perf_counter()
    bridge.start()
    try:
        seen_stylize, t0 = 0, None
        counts = {"steps": 0, "stylize_steps": 0, "snapshots": 0, "snapshot_mb": 0.0, "own_s": 0.0,
                  "paired": 0, "paired_s": 0.0}
        last_arrival: float | None = None  # when the last optimiser step's report arrived (None after a refit)
        while True:
            now = time.perf_counter()
            if bridge.state.error:
                raise SystemExit(f"the worker failed: {bridge.state.error}")
            if t0 is None and now - t_start > timeout:
                raise SystemExit(f"the worker did not reach its stylization within {timeout:g} s")
            if t0 is not None and (now - t0 >= seconds or bridge.state.done):
                break
            for kind, payload in bridge.poll():
                if kind == "report" and t0 is None and optimiser_report(payload):
                    seen_stylize += 1
                    if seen_stylize > skip:
                        t0, reached = time.perf_counter(), time.perf_counter() - t_start
                    continue
                if t0 is None:
                    continue
                if kind == "report":
                    counts["steps"] += 1
                    arrived = time.perf_counter()
                    if optimiser_report(payload):
                        counts["stylize_steps"] += 1
                        counts["own_s"] += float(payload.get("seconds") or 0.0)
                        if last_arrival is not None:
                            counts["paired"] += 1
                            counts["paired_s"] += arrived - last_arrival
                        last_arrival = arrived
                    else:
                        last_arrival = None
                elif kind == "snapshot":
                    counts["snapshots"] += 1
                    colours = payload[1].get("colors")
                    counts["snapshot_mb"] += 0.0 if colours is None else colours.nbytes / 1e6
            time.sleep(poll_s)
        wall = time.perf_counter() - t0
        decisions = bridge.state.decisions
        return {**counts, "wall": wall, "reached_s": reached, "device": decisions.get("device", "?"),
                "precision": decisions.get("precision", "?"), "done": bridge.state.done}
    finally:
        bridge.quit()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=None, help="scene file (default: the bundled demo)")
    p.add_argument("--style", default=None, help="painting (default: the bundled one)")
    p.add_argument("--preset", default="preview")
    p.add_argument("--device", default="auto")
    p.add_argument("--working-width", type=int, default=512)
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--skip", type=int, default=5, help="stylize steps not counted (the first ones warm up)")
    p.add_argument("--poll-ms", type=float, default=16.0, help="how often this side polls (a 60 Hz frame)")
    p.add_argument("--timeout", type=float, default=300.0, help="seconds the worker may take to reach stylize")
    p.add_argument("--worker-threads", type=int, default=1, help="the worker's torch threads (the studio's: 1)")
    args = p.parse_args()
    os.environ["GSTYLE_WORKER_THREADS"] = str(args.worker_threads)  # the spawned worker reads it
    config = {"scene": args.scene, "style": args.style, "preset": args.preset, "device": args.device,
              "working_width": args.working_width}
    print(f"CPU: {cpu_description()}")
    r = measure(config, args.seconds, args.skip, args.poll_ms / 1e3, args.timeout)
    print(f"device: {r['device']}; precision: {r['precision']}")
    print(f"stylization reached {r['reached_s']:.1f} s after the worker started; measured over {r['wall']:.1f} s"
          f"{' (the run ended first)' if r['done'] else ''}")
    stylize_rate, step_rate = r["stylize_steps"] / r["wall"], r["steps"] / r["wall"]
    own_rate = r["stylize_steps"] / max(r["own_s"], 1e-9)
    arrival_rate = r["paired"] / max(r["paired_s"], 1e-9)
    snap_rate = r["snapshots"] / r["wall"]
    print(f"{r['stylize_steps']} optimiser steps of {r['steps']}; worker torch threads {args.worker_threads}")
    print("| optimiser steps/s (own) | optimiser steps/s (arriving) | optimiser steps/s (wall) | all steps/s | "
          f"snapshots/s | colour MB/s |\n|---|---|---|---|---|---|\n| {own_rate:.1f} | {arrival_rate:.1f} | "
          f"{stylize_rate:.1f} | {step_rate:.1f} | {snap_rate:.1f} | {r['snapshot_mb'] / r['wall']:.1f} |")
    print(f"RESULT studio_own_steps_per_s={own_rate:.2f} studio_arriving_steps_per_s={arrival_rate:.2f} "
          f"studio_snapshots_per_s={snap_rate:.2f} width={args.working_width} device={args.device} "
          f"threads={args.worker_threads}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
