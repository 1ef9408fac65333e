"""Soak test: many fuzzed inputs per reader, then repeated short stylization runs.

Run: ``.venv/bin/python bench/soak.py [--cases-per-format 1000] [--runs 3] [--seed 0]``.

Every scene, camera and style-image format of ``tests/fuzzcases`` (the generators the fuzz tests use) gets
``--cases-per-format`` mutated inputs. A case fails when the reader raises anything but its one-line
``GStyleError``, returns an invalid result, allocates more than 64 MiB (tracemalloc) or runs longer than
10 s. Then ``--runs`` short stylizations of a tiny synthetic scene (a stand-in mean-colour objective, no VGG
weights needed) must finish with a valid scene. Prints a table per part and last
``RESULT cases=N failures=F peak_rss_mb=M`` (N fuzzed cases; F failed cases plus failed runs; M the
process's peak RSS from ``resource.getrusage``).

Reproduce one case with its traceback: ``--format ply-ascii --case 123`` (same ``--seed``).
"""

from __future__ import annotations

import argparse
import random
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gstyle_core.engine.settings import resolve_settings  # noqa: E402
from gstyle_core.engine.stylizer import Stylizer  # noqa: E402
from gstyle_core.io import validate_and_repair  # noqa: E402
from gstyle_core.machine import set_torch_threads  # noqa: E402
from tests.fakes import MeanColourPull  # noqa: E402
from tests.fuzzcases import (  # noqa: E402
    CAMERA_FORMATS,
    IMAGE_FORMATS,
    SCENE_FORMATS,
    FuzzFailure,
    RandomDraw,
    check_camera_source,
    check_scene_file,
    check_style_image,
    run_bounded,
    scene_case,
    write_camera_case,
    write_image_case,
)
from tests.fuzzcases.scenes import check_scene  # noqa: E402
from tests.synthetic import blob_scene, ring_cameras  # noqa: E402

CASE_TIMEOUT_S = 10
MAX_STEPS = 500


class CaseTimeout(Exception):
    """A case ran longer than CASE_TIMEOUT_S."""


def _alarm(signum, frame):
    raise CaseTimeout(f"no result after {CASE_TIMEOUT_S} s")


def run_case(fmt: str, seed: int, index: int, workdir: Path) -> tuple[str, float, int]:
    """Generate and check one case; returns (outcome, seconds, tracemalloc peak). Exceptions propagate."""
    draw = RandomDraw(random.Random(f"{seed}-{fmt}-{index}"))
    folder = Path(tempfile.mkdtemp(dir=workdir))
    try:
        if fmt in SCENE_FORMATS:
            data, suffix = scene_case(fmt, draw)
            target, check = folder / f"case{suffix}", check_scene_file
            target.write_bytes(data)
        elif fmt in CAMERA_FORMATS:
            target, check = write_camera_case(fmt, draw, folder), check_camera_source
        else:
            target, check = write_image_case(fmt, draw, folder / "style"), check_style_image
        signal.alarm(CASE_TIMEOUT_S)
        start = time.perf_counter()
        try:
            outcome, peak = run_bounded(check, target)
        finally:
            signal.alarm(0)
        return outcome, time.perf_counter() - start, peak
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def classify(exc: BaseException) -> str:
    if isinstance(exc, CaseTimeout):
        return "hang"
    if isinstance(exc, FuzzFailure):
        return "memory" if str(exc).startswith("allocated") else "contract"
    return type(exc).__name__


def fuzz(formats: list[str], cases: int, seed: int, workdir: Path) -> tuple[int, int]:
    """Run every format's cases and print one row per format; returns (cases run, failures)."""
    print(f"{'format':<15} {'cases':>6} {'ok':>6} {'error':>6} {'fail':>5} {'mean ms':>8} {'max ms':>8} "
          f"{'peak MiB':>8}  first failure")
    total = failed = 0
    for fmt in formats:
        counts: Counter[str] = Counter()
        times, peaks, first = [], [0], ""
        for i in range(cases):
            try:
                outcome, seconds, peak = run_case(fmt, seed, i, workdir)
                times.append(seconds)
                peaks.append(peak)
                counts[outcome] += 1
            except Exception as exc:  # the soak reports every failure kind and goes on
                kind = classify(exc)
                counts["fail"] += 1
                first = first or f"case {i}: {kind}: {str(exc).splitlines()[0][:70] if str(exc) else ''}"
        total += cases
        failed += counts["fail"]
        mean_ms = 1000 * sum(times) / max(len(times), 1)
        print(f"{fmt:<15} {cases:>6} {counts['ok']:>6} {counts['error']:>6} {counts['fail']:>5} {mean_ms:>8.1f} "
              f"{1000 * max(times, default=0):>8.1f} {max(peaks) / 2**20:>8.1f}  {first}", flush=True)
    return total, failed


def current_rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * resource.getpagesize() / 2**20


def stylize_runs(runs: int, seed: int) -> int:
    """Short stylizations of a 200-Gaussian scene; prints one row per run; returns the failed runs."""
    print(f"\n{'run':>4} {'seconds':>8} {'steps':>6} {'gaussians':>9} {'rss MiB':>8}  result")
    failed = 0
    for run in range(runs):
        rng = np.random.default_rng(seed + run)
        style = rng.uniform(0, 1, (16, 16, 3)).astype(np.float32)
        settings = resolve_settings("preview", "forward", 4, max_views=4, epochs=8, min_steps=0,
                                    refit_iterations=3, split_at=(0.5,), working_width=40,
                                    preprocess_rounds=1)
        start, steps, result = time.perf_counter(), 0, "ok"
        try:
            engine = Stylizer(blob_scene(200, seed=seed + run), ring_cameras(4), style, settings,
                              objective_factory=MeanColourPull)
            while not engine.done and steps < MAX_STEPS:
                report = engine.step()
                steps += 1
                if not all(np.isfinite(v) for v in report.losses.values()):
                    raise FuzzFailure(f"non-finite loss at step {steps}: {report.losses}")
            if not engine.done:
                raise FuzzFailure(f"not done after {MAX_STEPS} steps")
            scene = engine.stylized_scene()
            fields = (scene.means, scene.log_scales, scene.quats, scene.opacity_logits, scene.sh_dc)
            if not all(np.isfinite(a).all() for a in fields):
                raise FuzzFailure("non-finite stylized scene")
            # the optimiser leaves quaternions slightly off unit length (the rasterizer normalises them);
            # after the repairs every loaded file gets, the scene must be valid
            scene, repairs, dropped = validate_and_repair(scene)
            check_scene(scene)
            if dropped:
                raise FuzzFailure(f"{dropped} Gaussians had to be dropped")
            gaussians = scene.count
        except Exception as exc:  # reported in the table, counted as a failure
            result, gaussians = f"{type(exc).__name__}: {str(exc)[:60]}", 0
            failed += 1
        print(f"{run:>4} {time.perf_counter() - start:>8.2f} {steps:>6} {gaussians:>9} {current_rss_mb():>8.1f}  "
              f"{result}", flush=True)
    return failed


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases-per-format", type=int, default=1000, help="fuzzed inputs per format (default 1000)")
    p.add_argument("--runs", type=int, default=3, help="short stylization runs (default 3)")
    p.add_argument("--seed", type=int, default=0, help="seed of every generated case (default 0)")
    p.add_argument("--format", action="append", help="only this format (repeatable)")
    p.add_argument("--case", type=int, help="run this one case of --format and show its traceback")
    args = p.parse_args()
    formats = args.format or SCENE_FORMATS + CAMERA_FORMATS + IMAGE_FORMATS
    unknown = sorted(set(formats) - set(SCENE_FORMATS + CAMERA_FORMATS + IMAGE_FORMATS))
    if unknown:
        p.error(f"unknown format(s) {unknown}")
    signal.signal(signal.SIGALRM, _alarm)
    set_torch_threads(1)
    with tempfile.TemporaryDirectory(prefix="gstyle-soak-") as tmp:
        if args.case is not None:
            for fmt in formats:
                try:
                    print(fmt, args.case, run_case(fmt, args.seed, args.case, Path(tmp)))
                except Exception:
                    traceback.print_exc()
            return
        start = time.perf_counter()
        cases, failures = fuzz(formats, args.cases_per_format, args.seed, Path(tmp))
        print(f"fuzzing: {cases:,} cases in {time.perf_counter() - start:.0f} s")
    failures += stylize_runs(args.runs, args.seed)
    peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"RESULT cases={cases} failures={failures} peak_rss_mb={peak_rss_mb:.0f}")


if __name__ == "__main__":
    main()
