"""Whole stylization runs on each device side by side, with the result figures, on one machine.

For every ``--devices`` entry (default ``cpu,cuda`` where CUDA is seen, else ``cpu``) it builds the engine as
``gstyle stylize`` does (``--device``) after a warm-up (a whole small run on the device: imports, compiled kernels,
gsplat's module), runs the whole pipeline step by step and prints:

- the machine (CPU model and cores; the GPU, its driver and CUDA; torch), the precision each run chose and why;
- per device: engine build seconds, run seconds, per-phase seconds, stylize steps a second, peak GPU memory;
- the result figures of each run (NNFM drop and structure kept, ``evaluate_run``: measured on the CPU in fp32
  for every run, so that they compare), and each device's difference from the first device's;
- with ``--rate-width W``: the stylize steps a second of an engine working at W px (the studio's live rate), after
  its first 5 steps.

    .venv/bin/python bench/device_stylize.py [SCENE] [--style IMAGE] [--preset preview] [--devices cpu,cuda]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gstyle_core.engine.build import (  # noqa: E402
    SETTING_OPTIONS,  # noqa: E402
    BuildRequest,
    build_stylizer,
)
from gstyle_core.engine.phases.stylize import is_optimiser_step  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402


def gpu_description() -> str:
    """The card, its driver and torch's CUDA, or a line saying there is none."""
    if not torch.cuda.is_available():
        return "no CUDA device seen by torch"
    try:
        driver = subprocess.run(["nvidia-smi", "--query-gpu=driver_version", "--format=csv,noheader"],
                                capture_output=True, text=True, timeout=20).stdout.strip()
    except (OSError, subprocess.TimeoutExpired):
        driver = "unknown"
    return f"{torch.cuda.get_device_name(0)}, driver {driver}, CUDA {torch.version.cuda}"


def sync(device: str) -> None:
    if device == "cuda":
        torch.cuda.synchronize()


def build(args: argparse.Namespace, device: str, precision: str, **overrides):
    values = {name: None for name in SETTING_OPTIONS}
    values.update(device=device, precision=precision, **overrides)
    request = BuildRequest(scene=args.scene, style=args.style, preset=args.preset, scene_kind="auto",
                           overrides=values)
    return build_stylizer(request)


def warm_up(device: str, precision: str) -> None:
    """A whole small run first (the demo at 64 px, one epoch, 5 refit iterations) on the device at the timed run's
    precision: every module imported, every kernel compiled, gsplat's module loaded (built once if need be): the
    one-time costs a studio session pays once, not per run."""
    demo = argparse.Namespace(scene=None, style=None, preset="preview")
    engine = build(demo, device, precision, working_width=64, epochs=1.0, refit_iterations=5,
                   preprocess_rounds=1).engine
    while not engine.done:
        engine.step()
    sync(device)


def run_once(args: argparse.Namespace, device: str, precision: str) -> dict:
    """Build and run one engine to the end; per-phase seconds, figures."""
    from gstyle_core.engine.run_figures import evaluate_run

    warm_up(device, precision)
    if device == "cuda":
        torch.cuda.reset_peak_memory_stats()
    t0 = time.perf_counter()
    built = build(args, device, precision)
    engine = built.engine
    sync(device)
    build_s = time.perf_counter() - t0
    phases: dict[str, float] = defaultdict(float)
    stylize_steps = 0
    t1 = time.perf_counter()
    while not engine.done:
        ts = time.perf_counter()
        rep = engine.step()
        sync(device)
        phases[rep.phase] += time.perf_counter() - ts
        stylize_steps += is_optimiser_step(rep.phase, rep.message)
    run_s = time.perf_counter() - t1
    peak = torch.cuda.max_memory_allocated() / 2**30 if device == "cuda" else 0.0
    quality = evaluate_run(engine, built.scene, built.style, display_width=0)
    return {"device": device, "build_s": build_s, "run_s": run_s, "phases": dict(phases), "peak_gib": peak,
            "gaussians": engine.run_state.gaussian_count, "stylize_steps": stylize_steps,
            "stylize_s": phases.get("stylize", 0.0), "drop": quality["nnfm_drop"], "structure": quality["structure"],
            "precision": engine.decisions.get("precision"), "device_note": engine.decisions.get("device")}


def step_rate(args: argparse.Namespace, device: str, width: int, steps: int = 40) -> tuple[float, float]:
    """At ``width`` px, once the run reaches its stylization (its first 5 steps not timed): stylize steps a second
    counting only their own time, and counting the splits' refits between them too."""
    engine = build(args, device, "auto", working_width=width).engine
    while not engine.done and engine.phase != "stylize":
        engine.step()
    for _ in range(5):
        engine.step()
    sync(device)
    t0, done, own = time.perf_counter(), 0, 0.0
    while done < steps and not engine.done:
        ts = time.perf_counter()
        rep = engine.step()
        sync(device)
        if is_optimiser_step(rep.phase, rep.message):
            done, own = done + 1, own + time.perf_counter() - ts
    return done / max(own, 1e-9), done / (time.perf_counter() - t0)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=None, help="scene file (default: the bundled demo)")
    p.add_argument("--style", default=None, help="painting (default: the bundled one)")
    p.add_argument("--preset", default="preview", choices=["preview", "balanced", "final"])
    p.add_argument("--devices", default=None, help="comma-separated: cpu, cuda (default: cpu,cuda where CUDA is)")
    p.add_argument("--cpu-precision", default="fp32", help="the CPU run's precision (the reference: fp32)")
    p.add_argument("--gpu-precision", default="auto", help="the CUDA run's precision (auto: bf16 where native)")
    p.add_argument("--rate-width", type=int, default=0, help="also measure stylize steps/s at this width (CUDA)")
    args = p.parse_args()
    devices = (args.devices or ("cpu,cuda" if torch.cuda.is_available() else "cpu")).split(",")
    print(f"CPU: {cpu_description()}; torch {torch.__version__}, {torch.get_num_threads()} threads")
    print(f"GPU: {gpu_description()}")
    print(f"scene {args.scene or 'bundled demo'}, style {args.style or 'bundled'}, preset {args.preset}")
    rows = []
    for device in devices:
        precision = args.gpu_precision if device == "cuda" else args.cpu_precision
        row = run_once(args, device, precision)
        rows.append(row)
        print(f"[{device}] device: {row['device_note']}; precision: {row['precision']}", flush=True)
        phases = ", ".join(f"{k} {v:.2f}" for k, v in row["phases"].items())
        print(f"[{device}] build {row['build_s']:.2f} s, run {row['run_s']:.2f} s ({phases}); "
              f"{row['stylize_steps']} stylize steps at {row['stylize_steps'] / max(row['stylize_s'], 1e-9):.1f}/s; "
              f"{row['gaussians']:,} Gaussians; peak GPU memory {row['peak_gib']:.2f} GiB", flush=True)
    print("\n| device | precision | build s | run s | stylize steps/s | NNFM drop | structure | Δdrop (pts) | "
          "Δstructure |\n|---|---|---|---|---|---|---|---|---|")
    ref = next((r for r in rows if r["device"] == "cpu"), rows[0])  # differences from the CPU's run
    for r in rows:
        print(f"| {r['device']} | {str(r['precision']).split(':')[0]} | {r['build_s']:.2f} | {r['run_s']:.2f} | "
              f"{r['stylize_steps'] / max(r['stylize_s'], 1e-9):.1f} | {100 * r['drop']:.1f} % | "
              f"{r['structure']:.3f} | {100 * (r['drop'] - ref['drop']):+.1f} | "
              f"{r['structure'] - ref['structure']:+.3f} |")
    if args.rate_width and "cuda" in devices:
        own, overall = step_rate(args, "cuda", args.rate_width)
        print(f"RESULT cuda_steps_per_s_at_{args.rate_width}px={own:.1f} (with the refits between them: "
              f"{overall:.1f})")
    for r in rows:
        print(f"RESULT {r['device']}_run_s={r['run_s']:.2f} {r['device']}_drop={r['drop']:.4f} "
              f"{r['device']}_structure={r['structure']:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
