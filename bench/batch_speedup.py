"""Issue #50's batch target: the atlas's 2 scenes × 3 paintings, six ``gstyle stylize`` runs one after another
against one ``gstyle batch`` with several jobs at once, in one run on this machine.

    python bench/batch_speedup.py [--jobs 4] [--threads 4] [--preset preview] [--device cpu] [--fern PATH]
                                  [--scenes fountain,fern] [--paintings starry,wave,autumn]

The six runs are what an artist types by hand: one ``python -m gstyle_core.cli stylize`` process per pair, each with
torch's own threads (every core), the fern with its LLFF cameras. The batch runs the same jobs from the atlas's plan
(``bench/tradeoff.py``'s ``write_plan``) with ``--jobs`` at a time and ``--threads`` each. Both use the preset's
other defaults (the display's figures included) and ``--force``. Wall time of each whole part (processes, imports,
figures and the batch's contact sheet included), the ratio, and whether every job's OUT.json reports the same
figures both ways (same seeds; threads may change the last digits). ``RESULT`` line last.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import tradeoff  # noqa: E402

from gstyle_core.errors import GStyleError  # noqa: E402


def stylize_argv(scene: Path, cameras: Path | None, painting: Path, out: Path, options: list[str]) -> list[str]:
    """One ``gstyle stylize`` as a process, as an artist runs it."""
    cams = [] if cameras is None else ["--cameras", str(cameras)]
    return [sys.executable, "-m", "gstyle_core.cli", "stylize", str(scene), "--style", str(painting), *cams,
            *options, "--out", str(out), "--force"]


def one_after_another(scenes: dict, paintings: dict, folder: Path, options: list[str]) -> tuple[float, dict]:
    """The six runs one after another: wall seconds and each pair's OUT.json."""
    folder.mkdir(parents=True, exist_ok=True)
    outs, t0 = {}, time.perf_counter()
    for scene_name, (scene, cams) in scenes.items():
        for painting_name, painting in paintings.items():
            out = folder / f"{scene_name}__{painting_name}.ply"
            log = out.with_suffix(".log")
            with log.open("w", encoding="utf-8") as fh:
                code = subprocess.run(stylize_argv(scene, cams, painting, out, options), stdout=fh,
                                      stderr=subprocess.STDOUT, cwd=ROOT, check=False).returncode
            if code:
                raise GStyleError(f"gstyle stylize {scene_name} / {painting_name} failed ({code}): see {log}")
            outs[(str(scene), str(painting))] = out.with_suffix(".json")
    return time.perf_counter() - t0, outs


def batched(scenes: dict, paintings: dict, folder: Path, options: list[str], jobs: int, threads: int):
    """The same jobs as one ``gstyle batch``: wall seconds and each pair's OUT.json."""
    plan = tradeoff.write_plan(folder / "plan.toml", scenes, paintings)
    t0 = time.perf_counter()
    code = subprocess.run([sys.executable, "-m", "gstyle_core.cli", "batch", "--plan", str(plan), *options,
                           "--jobs", str(jobs), "--threads", str(threads), "--force", "--out", str(folder / "out")],
                          cwd=ROOT, check=False).returncode
    seconds = time.perf_counter() - t0
    if code:
        raise GStyleError(f"gstyle batch failed ({code}): see {folder / 'out' / 'logs'}")
    return seconds, tradeoff.job_outputs(folder / "out")


def figures(summary: Path) -> tuple[float, float, float]:
    """A job's NNFM drop, structure and the seconds its OUT.json records."""
    s = json.loads(summary.read_text(encoding="utf-8"))
    return s["quality"]["nnfm_drop"], s["quality"]["structure"], s["seconds_total"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--jobs", type=int, default=4, help="the batch's jobs at a time")
    p.add_argument("--threads", type=int, default=4, help="torch threads per batch job")
    p.add_argument("--preset", default="preview")
    p.add_argument("--device", default="cpu", help="both parts' --device")
    p.add_argument("--fern", default=None, help="a fitted fern (default: bench/tradeoff.py's)")
    p.add_argument("--paintings", default=",".join(tradeoff.ATLAS_PAINTINGS))
    p.add_argument("--scenes", default="fountain,fern", help="comma-separated, of the atlas's scenes")
    p.add_argument("--work", default=str(ROOT / "out" / "batch_speedup"))
    args = p.parse_args(argv)
    from gstyle_core.machine import cpu_info
    from gstyle_core.paths import cache_dir

    fern = Path(args.fern) if args.fern else cache_dir() / "atlas" / "fern.ply"
    paintings = {n: tradeoff.PAINTINGS[n].resolve()  # checked before the fern, which may be fitted first
                 for n in tradeoff.selected(args.paintings, tradeoff.PAINTINGS, "painting")}
    scenes = {n: (s.resolve(), None if c is None else c.resolve())
              for n, (s, c) in tradeoff.scene_paths(args.scenes.split(","), fern).items()}
    options = ["--preset", args.preset, "--device", args.device]
    work = Path(args.work)
    cpu = cpu_info()
    print(f"machine: {cpu.model}, {cpu.cores} cores; {len(scenes)} scenes x {len(paintings)} paintings, "
          f"{args.preset}, --device {args.device}; load average {tradeoff.load_average():.2f}", flush=True)
    seq_s, seq = one_after_another(scenes, paintings, work / "one_after_another", options)
    print(f"one after another: {seq_s:.1f} s; load average {tradeoff.load_average():.2f}", flush=True)
    bat_s, bat = batched(scenes, paintings, work / "batch", options, args.jobs, args.threads)
    print(f"batch: {bat_s:.1f} s; load average {tradeoff.load_average():.2f}", flush=True)
    print(f"\n| how | settings | wall time |\n|---|---|---|\n"
          f"| {len(seq)} `gstyle stylize` one after another | torch's threads ({cpu.cores}) | {seq_s:.1f} s |\n"
          f"| `gstyle batch --jobs {args.jobs} --threads {args.threads}` | {args.jobs} jobs at a time | "
          f"{bat_s:.1f} s ({seq_s / bat_s:.2f}x faster) |\n")
    print("| scene / painting | drop (alone / batch) | structure (alone / batch) | seconds in OUT.json |")
    print("|---|---|---|---|")
    same = True
    for key, summary in seq.items():
        a = figures(summary)
        b = figures(bat[key]) if key in bat else (float("nan"),) * 3
        same &= abs(a[0] - b[0]) <= 0.01 and abs(a[1] - b[1]) <= 0.02
        print(f"| {Path(key[0]).stem} / {Path(key[1]).stem} | {100 * a[0]:.1f} / {100 * b[0]:.1f} % | "
              f"{a[1]:.3f} / {b[1]:.3f} | {a[2]:.1f} / {b[2]:.1f} s |")
    print(f"RESULT one_after_another_s={seq_s:.1f} batch_s={bat_s:.1f} speedup={seq_s / bat_s:.2f} "
          f"jobs={args.jobs} threads={args.threads} same_figures={same}")
    return 0


if __name__ == "__main__":
    tradeoff.run_script(main, "batch_speedup.py")
