"""The host's share of a stylize step that grows with the Gaussians: the colours' bookkeeping around the loss.

Whatever device computes the networks, a step's colours live on the CPU: ``ColourSteps.begin`` / ``finish`` (the
coarse colour field's gradient and fold, Adam on the colours and on the field, the clamp and the scatter into c_s)
run there, one thread in the studio's worker. On a GPU they are host time the GPU waits for. This bench prints:

1. ``VisibleAdam.step`` at 56k, 288k and 1M rows (half in view), its one-pass step beside the step written with
   torch's operators, in one process (median of 12 after a warm-up);
2. ``begin`` + ``finish`` per optimiser step of a real run: the bundled demo replicated 1× and 4× (each copy jittered),
   64 px working width (the networks' cost is not what is measured: a stand-in objective pulls the mean colour),
   preview settings of a 360° scene with the colour field on; the median over the optimiser steps after the first.

Usage: .venv/bin/python bench/studies/colour_steps.py [--copies 1 4] [--rows 56000 288000 1000000]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "bench"))

from bench_memory_per_gaussian import replicated_demo  # noqa: E402 (the scene of the memory bench, in bench/)

from gstyle_core.engine import colour_steps  # noqa: E402
from gstyle_core.engine.visible_adam import VisibleAdam  # noqa: E402
from gstyle_core.machine import cpu_description, set_torch_threads  # noqa: E402


def adam_ms(rows: int, by_operators: bool, repeats: int = 12) -> float:
    """Median ms of a ``VisibleAdam`` step on [rows, 3] with half the rows in view."""
    param = torch.rand(rows, 3, generator=torch.Generator().manual_seed(0)).requires_grad_(True)
    optimiser = VisibleAdam(param, lr=0.01)
    grad = torch.zeros(rows, 3)
    seen = torch.randperm(rows, generator=torch.Generator().manual_seed(1))[: rows // 2]
    grad[seen] = torch.randn(len(seen), 3, generator=torch.Generator().manual_seed(2))
    step = optimiser.step_by_operators if by_operators else optimiser.step
    times = []
    for _ in range(repeats + 1):
        param.grad = grad.clone()
        started = time.perf_counter()
        step()
        times.append(time.perf_counter() - started)
    return 1e3 * statistics.median(times[1:])


def bookkeeping_ms(copies: int) -> tuple[int, float, float, int]:
    """(Gaussians, median ms of ``begin``, of ``finish``, steps timed) of a run on the demo ``copies`` times."""
    from fakes import MeanColourPull

    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer

    scene, cameras = replicated_demo(copies)
    settings = resolve_settings("preview", "360", len(cameras), working_width=64, preprocess_rounds=0,
                                colour_field=True, epochs=3.0, min_steps=0)
    style = np.random.default_rng(1).uniform(0, 1, (64, 64, 3)).astype(np.float32)
    engine = Stylizer(scene, cameras, style, settings, objective_factory=MeanColourPull)
    times: dict[str, list[float]] = {"begin": [], "finish": []}
    originals = {name: getattr(colour_steps.ColourSteps, name) for name in times}

    def timed(name):
        def run(self, *args, **kwargs):
            warm = self.optimiser is not None  # the first step builds the optimiser and the field: not timed
            started = time.perf_counter()
            out = originals[name](self, *args, **kwargs)
            if warm:
                times[name].append(time.perf_counter() - started)
            return out
        return run

    try:
        for name in times:
            setattr(colour_steps.ColourSteps, name, timed(name))
        while not engine.done:
            engine.step()
    finally:
        for name, method in originals.items():
            setattr(colour_steps.ColourSteps, name, method)
    begin, finish = times["begin"][1:], times["finish"][1:]
    return engine.gaussian_count, 1e3 * statistics.median(begin), 1e3 * statistics.median(finish), len(finish)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--copies", type=int, nargs="+", default=[1, 4])
    p.add_argument("--rows", type=int, nargs="+", default=[56_000, 288_000, 1_000_000])
    args = p.parse_args()
    set_torch_threads(1)
    print(f"CPU: {cpu_description()}; torch {torch.__version__}, 1 thread")
    print("\n| VisibleAdam.step, half the rows in view | one pass (ms) | torch's operators (ms) | ratio |")
    print("|---|---|---|---|")
    for rows in args.rows:
        fast, slow = adam_ms(rows, False), adam_ms(rows, True)
        print(f"| {rows:,} rows | {fast:.1f} | {slow:.1f} | {slow / fast:.1f}× |")
    print("\n| demo × copies, 64 px, colour field on | Gaussians | begin (ms) | finish (ms) | per step (ms) | steps |")
    print("|---|---|---|---|---|---|")
    for copies in args.copies:
        count, begin, finish, steps = bookkeeping_ms(copies)
        print(f"| × {copies} | {count:,} | {begin:.1f} | {finish:.1f} | {begin + finish:.1f} | {steps} |")
        print(f"RESULT colour_bookkeeping_ms={begin + finish:.2f} gaussians={count}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
