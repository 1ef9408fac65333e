"""Where a stylize step's time goes on a device: torch's profiler over a few optimiser steps of the demo.

Builds the demo's engine (``--preset``, ``--working-width``, ``--device``), runs it to its stylization, takes
``--skip`` optimiser steps untimed, then profiles the engine's steps one by one and keeps the next ``--steps``
optimiser steps (splits and refits between them are left out). Prints the wall time per step, the device's busy time
per step, the kernel launches and torch operator calls per step and the ``--top`` operators by their own CPU time
and by their own device time. Then, over as many further optimiser steps, without the profiler: the operators a step
dispatches that compute (views of tensors left out: on a GPU each of the others launches at least one kernel; the
count does not depend on the device, so the CPU measures it too) and, on CUDA, the times a step makes the CPU wait
for the GPU (reads of values, copies from or to the CPU's pageable memory: torch's sync debug mode).

    python bench/device_profile.py [--device cuda] [--working-width 512] [--steps 8] [--scene-kind forward]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from collections import Counter, defaultdict
from pathlib import Path

import torch
from torch.profiler import ProfilerActivity, profile
from torch.utils._python_dispatch import TorchDispatchMode

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gstyle_core.engine.build import SETTING_OPTIONS, BuildRequest, build_stylizer  # noqa: E402
from gstyle_core.engine.phases.stylize import is_optimiser_step  # noqa: E402


def next_optimiser_step(engine) -> None:
    """Step the engine until one stylization optimiser step was taken."""
    while not engine.done:
        rep = engine.step()
        if is_optimiser_step(rep.phase, rep.message):
            return


def profiled_optimiser_steps(engine, steps: int, cuda: bool) -> tuple[dict[str, list[float]], float]:
    """Profile engine steps one by one until ``steps`` optimiser steps were taken, keeping only theirs: per operator
    [own CPU us, own device us, calls], and their wall seconds (splits and refits between them are left out)."""
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if cuda else [])
    totals: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0.0])
    wall, kept = 0.0, 0
    while kept < steps and not engine.done:
        if cuda:
            torch.cuda.synchronize()
        with profile(activities=activities) as prof:
            t0 = time.perf_counter()
            rep = engine.step()
            if cuda:
                torch.cuda.synchronize()
            seconds = time.perf_counter() - t0
        if not is_optimiser_step(rep.phase, rep.message):
            continue
        kept, wall = kept + 1, wall + seconds
        for e in prof.key_averages():
            row = totals[e.key]
            row[0] += e.self_cpu_time_total
            row[1] += e.self_device_time_total if cuda else 0.0
            row[2] += e.count
    return dict(totals), wall / max(kept, 1)


class DispatchCount(TorchDispatchMode):
    """Counts the operators dispatched that compute (views, aliases and detaches left out), by name."""

    def __init__(self) -> None:
        super().__init__()
        self.names: Counter[str] = Counter()

    @property
    def count(self) -> int:
        """The computing operators dispatched so far."""
        return sum(self.names.values())

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        if not (func.is_view or func.__name__.split(".")[0] in ("detach", "lift_fresh", "_unsafe_view")):
            self.names[func.__name__] += 1
        return func(*args, **(kwargs or {}))


def counted_optimiser_steps(engine, steps: int, cuda: bool) -> tuple[float, float | None]:
    """Over the next ``steps`` optimiser steps (others are left out): the computing operators dispatched a step and,
    on CUDA, the waits for the GPU a step (warnings of torch's sync debug mode; None elsewhere)."""
    ops = syncs = kept = 0
    while kept < steps and not engine.done:
        counter = DispatchCount()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            if cuda:
                torch.cuda.set_sync_debug_mode("warn")
            try:
                with counter:
                    rep = engine.step()
            finally:
                if cuda:
                    torch.cuda.set_sync_debug_mode("default")
        if not is_optimiser_step(rep.phase, rep.message):
            continue
        kept += 1
        ops += counter.count
        syncs += sum("synchroniz" in str(w.message) for w in caught)
    kept = max(kept, 1)
    return ops / kept, (syncs / kept if cuda else None)


def top_rows(totals: dict[str, list[float]], column: int, count: int, steps: int) -> str:
    """The ``count`` operators with the most of ``column`` (0: own CPU time, 1: own device time, 2: calls)."""
    lines = ["| operator | own CPU ms/step | own device ms/step | calls/step |", "|---|---|---|---|"]
    for name, (cpu, dev, calls) in sorted(totals.items(), key=lambda kv: -kv[1][column])[:count]:
        lines.append(f"| {name[:60]} | {cpu / 1e3 / steps:.2f} | {dev / 1e3 / steps:.2f} | {calls / steps:.0f} |")
    return "\n".join(lines)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cuda")
    p.add_argument("--preset", default="preview")
    p.add_argument("--scene-kind", default="auto", choices=["auto", "forward", "360"],
                   help="the demo as a 360° scene (auto) or as a forward-facing one: that kind's terms and weights")
    p.add_argument("--working-width", type=int, default=512)
    p.add_argument("--skip", type=int, default=5)
    p.add_argument("--steps", type=int, default=8)
    p.add_argument("--top", type=int, default=12)
    args = p.parse_args()
    values = {name: None for name in SETTING_OPTIONS}
    values.update(device=args.device, working_width=args.working_width)
    engine = build_stylizer(BuildRequest(preset=args.preset, scene_kind=args.scene_kind, overrides=values)).engine
    cuda = args.device == "cuda"
    for _ in range(args.skip):
        next_optimiser_step(engine)
    totals, per_step = profiled_optimiser_steps(engine, args.steps, cuda)
    n = args.steps
    device_us = sum(row[1] for row in totals.values())
    launches = sum(totals.get(k, [0, 0, 0])[2] for k in ("cudaLaunchKernel", "cuLaunchKernel", "cudaLaunchKernelExC"))
    aten_calls = sum(row[2] for name, row in totals.items() if name.startswith("aten::"))
    print(f"{args.device}, {args.working_width} px, preset {args.preset}, scene kind {args.scene_kind}: "
          f"{1e3 * per_step:.1f} ms an optimiser step "
          f"(wall, profiler on), device busy {device_us / 1e3 / n:.1f} ms, {launches / n:.0f} kernel launches, "
          f"{aten_calls / n:.0f} aten calls a step")
    print(top_rows(totals, 0, args.top, n))
    for column in ((1, 2) if cuda else (2,)):
        print()
        print(top_rows(totals, column, args.top, n))
    ops, syncs = counted_optimiser_steps(engine, args.steps, cuda)
    waits = "" if syncs is None else f", {syncs:.0f} waits for the GPU"
    print(f"\nwithout the profiler, {args.steps} more optimiser steps: {ops:.0f} computing operators dispatched a "
          f"step{waits}")
    print(f"RESULT profile_ms_per_step={1e3 * per_step:.1f} device_ms_per_step={device_us / 1e3 / n:.1f} "
          f"launches_per_step={launches / n:.0f} aten_calls_per_step={aten_calls / n:.0f} "
          f"dispatched_ops_per_step={ops:.0f}" + ("" if syncs is None else f" gpu_waits_per_step={syncs:.1f}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
