"""The engine at the sizes artists' captures have: ``gstyle stylize`` on captures of 0.15-6 M Gaussians.

The scenes are made from a real capture (default ``biker.spz``, 152,746 Gaussians) by ``densify.py``: each
Gaussian replaced by children sampled inside it (seeded); a size at most the capture's count is its first rows, as
they are. Per size, one after another in this one run, each in a fresh process:

* ``gstyle stylize SCENE --preset PRESET`` (default ``preview``) after ``--style``: its seconds per phase and in all
  (OUT.json), its steps, the Gaussians in and out, its peak resident memory (the child's ``ru_maxrss`` from
  ``os.wait4``) in bytes per input Gaussian, and its figures: NNFM drop and structure at the working width, speckle
  at 1024 px;
* the result written as ``.ply``, ``.spz`` and ``.compressed.ply`` and read back (``gstyle_core.io``), timed, with
  the count read back checked against the count written (``--no-export`` skips this).

Before the first size, one tiny run (``GSTYLE_SMOKE=1`` on the bundled demo, untimed) pays what only a machine's
first run pays: numba's compiled kernels written to their cache, VGG-16 converted into the cache folder, the
precision timed for this CPU; without it the first size's time holds them (``--no-warmup``).

``--lod auto on off`` runs each size with each level-of-detail setting (``auto``, the engine's default, cuts a capture
denser than 4 Gaussians a pixel; ``--lod-pixels`` sets the cut's cell size), and a table compares the figures of
each run on a cut with the same size's ``--lod off`` run; ``--shuffle`` writes each capture's rows in a random order.

Beside the per-size figures, the memory slope: (peak of a size - peak of the smallest) / (its Gaussians - the
smallest's), the bytes an extra Gaussian costs once the fixed part (torch, the networks) is paid.

    .venv/bin/python bench/engine_scale.py [--sizes 150000,1200000,6000000] [--preset preview] [--threads N]
                                           [--lod auto|on|off ...] [--lod-pixels PX ...] [--shuffle]

Last line: ``RESULT sizes=… seconds=… bytes_per_gaussian=… ratio_1.2M_to_150k=…`` (seconds and bytes per size in
the order of ``--sizes``; the ratio is the 1.2 M run's seconds over the 150k run's, where both were asked for).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from densify import densify  # noqa: E402

from gstyle_core.io import load_scene, save_scene  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402

SHARED = Path(os.environ.get("GSTYLE_SHARED_DATA", ROOT.parent / "shared" / "data"))  # a copy elsewhere: the env
SOURCE = SHARED / "scenes" / "playcanvas" / "biker.spz"
STYLE = SHARED / "styles" / "starry_night_vangogh.jpg"
EXPORTS = (".ply", ".spz", ".compressed.ply")


def parse_sizes(text: str) -> list[int]:
    """``150000,1.2M,6e6`` -> [150000, 1200000, 6000000]."""
    sizes = []
    for part in text.split(","):
        part = part.strip().lower()
        scale = 1_000_000 if part.endswith("m") else 1_000 if part.endswith("k") else 1
        sizes.append(int(float(part.rstrip("mk")) * scale))
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"sizes must be positive counts, got {text!r}")
    return sizes


def run_stylize(scene: Path | None, out: Path, args: argparse.Namespace, smoke: bool = False,
                lod: str = "on", lod_pixels: float | None = None) -> dict:
    """``gstyle stylize`` in a fresh process (``scene`` None: the bundled demo; ``smoke``: with ``GSTYLE_SMOKE=1``,
    the tiniest run; ``lod``: its ``--lod``): its OUT.json with the child's peak RSS and wall time added."""
    command = [sys.executable, "-m", "gstyle_core.cli", "stylize", *([str(scene)] if scene else []),
               "--preset", args.preset, "--out", str(out), "--force", "--lod", lod]
    if lod != "off" and lod_pixels:
        command += ["--lod-pixels", str(lod_pixels)]
    if args.style:
        command += ["--style", str(args.style)]
    if args.threads:
        command += ["--threads", str(args.threads)]
    log = out.with_suffix(".log")
    t0 = time.perf_counter()
    with open(log, "w") as fh:
        env = dict(os.environ, GSTYLE_SMOKE="1") if smoke else None
        child = subprocess.Popen(command, stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT, env=env)
        _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        tail = log.read_text(errors="replace").replace("\r", "\n").splitlines()[-5:]
        name = scene.name if scene else "the demo"
        raise SystemExit(f"gstyle stylize on {name} failed (exit {code}): " + " | ".join(tail))
    record = json.loads(out.with_suffix(".json").read_text())
    record["wall_seconds"] = wall
    record["peak_rss"] = usage.ru_maxrss * 1024  # kB on Linux
    return record


def export_round_trips(path: Path, folder: Path) -> list[dict]:
    """The result at ``path`` written in every export format and read back: seconds, size, counts."""
    scene, _ = load_scene(path)
    rows = []
    for suffix in EXPORTS:
        target = folder / f"export{suffix}"
        t0 = time.perf_counter()
        save_scene(scene, target)
        written = time.perf_counter() - t0
        t0 = time.perf_counter()
        back, _ = load_scene(target)
        read = time.perf_counter() - t0
        rows.append({"format": suffix, "write_s": written, "read_s": read, "mb": target.stat().st_size / 2**20,
                     "count": scene.count, "count_back": back.count})
        target.unlink()
        del back
    return rows


def figures(record: dict) -> dict:
    """The per-size row of the table."""
    q = record["quality"]
    return {"n": record["gaussians_before"], "out": record["gaussians_after"], "steps": record.get("steps"),
            "seconds": record["seconds_total"], "wall": record["wall_seconds"], "phases": record["seconds_per_phase"],
            "peak": record["peak_rss"], "bytes_per_gaussian": record["peak_rss"] / record["gaussians_before"],
            "drop": q["nnfm_drop"], "structure": q["structure"],
            "speckle": (q.get("display") or {}).get("speckle_ratio"),
            "capacity": record["decisions"].get("capacity", ""), "lod": str(record["settings"].get("lod", "off")),
            "lod_pixels": record["settings"].get("lod_pixels"), "cut": record["decisions"].get("lod", "")}


def print_tables(rows: list[dict]) -> None:
    """Per size: time, phases, memory, figures; then the export round trips."""
    phases = sorted({p for r in rows for p in r["phases"]}, key=lambda p: [*rows[0]["phases"], p].index(p))
    print("\n| Gaussians in | lod | out | steps | seconds | " + " | ".join(phases)
          + " | peak RSS | bytes/Gaussian | slope | drop | structure | speckle |")
    print("|" + "---|" * (11 + len(phases)))
    for r in rows:
        base = next(b for b in rows if _lod_label(b) == _lod_label(r))  # the smallest size with the same --lod
        slope = ((r["peak"] - base["peak"]) / (r["n"] - base["n"])) if r["n"] != base["n"] else float("nan")
        speckle = "-" if r["speckle"] is None else f"{r['speckle']:.2f}"
        print(f"| {r['n']:,} | {_lod_label(r)} | {r['out']:,} | {r['steps']} | {r['seconds']:.0f} | "
              + " | ".join(f"{r['phases'].get(p, 0):.1f}" for p in phases)
              + f" | {r['peak'] / 2**30:.2f} GiB | {r['bytes_per_gaussian']:,.0f} | {slope:,.0f} | "
                f"{100 * r['drop']:.1f} % | {r['structure']:.2f} | {speckle} |")
    for r in rows:
        if r["capacity"]:
            print(f"capacity at {r['n']:,}: {r['capacity']}")
        if r["lod"] != "off":
            print(f"level of detail at {r['n']:,} ({_lod_label(r)}): {r['cut']}")
    print_lod_comparison(rows)
    if any(r.get("exports") for r in rows):
        print("\n| Gaussians | format | write s | read s | MB | read back |")
        print("|---|---|---|---|---|---|")
        for r in rows:
            for e in r.get("exports", []):
                ok = "same count" if e["count_back"] == e["count"] else f"{e['count_back']:,} of {e['count']:,}"
                print(f"| {e['count']:,} | {e['format']} | {e['write_s']:.1f} | {e['read_s']:.1f} | {e['mb']:.0f} | "
                      f"{ok} |")


def print_lod_comparison(rows: list[dict]) -> None:
    """Where a size ran with the level of detail on and off: the figures' differences and the time's ratio."""
    pairs = [(a, b) for a in rows for b in rows if a["n"] == b["n"] and a["lod"] != "off" and b["lod"] == "off"]
    if not pairs:
        return
    print("\n| Gaussians | lod | seconds on / off | drop on - off | structure on - off | speckle on / off |")
    print("|---|---|---|---|---|---|")
    for on, off in pairs:
        speckle = ("-" if on["speckle"] is None or not off["speckle"] else f"{on['speckle'] / off['speckle']:.2f}")
        print(f"| {on['n']:,} | {_lod_label(on)} | {on['seconds'] / off['seconds']:.2f} | "
              f"{on['drop'] - off['drop']:+.3f} | {on['structure'] - off['structure']:+.3f} | {speckle} |")


def _lod_label(row: dict) -> str:
    """A run's level of detail in the tables: "off", or "on" and its cell size."""
    return f"{row['lod']} {row['lod_pixels']:g} px" if row["lod"] != "off" else "off"


def result_line(rows: list[dict]) -> str:
    """The RESULT line (module docstring): of the runs with the first ``--lod`` (and ``--lod-pixels``) asked for."""
    rows = [r for r in rows if _lod_label(r) == _lod_label(rows[0])]
    by_n = {r["n"]: r for r in rows}
    ratio = (f"{by_n[1_200_000]['seconds'] / by_n[150_000]['seconds']:.2f}"
             if 1_200_000 in by_n and 150_000 in by_n else "na")
    return ("RESULT sizes=" + ",".join(str(r["n"]) for r in rows)
            + " seconds=" + ",".join(f"{r['seconds']:.0f}" for r in rows)
            + " bytes_per_gaussian=" + ",".join(f"{r['bytes_per_gaussian']:.0f}" for r in rows)
            + f" ratio_1.2M_to_150k={ratio}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sizes", type=parse_sizes, default=parse_sizes("150000,1200000,6000000"))
    p.add_argument("--source", type=Path, default=SOURCE, help="the real capture to densify")
    p.add_argument("--style", type=Path, default=STYLE if STYLE.exists() else None,
                   help="painting (default The Starry Night from ../shared, else the bundled one)")
    p.add_argument("--preset", default="preview", choices=("preview", "balanced", "final"))
    p.add_argument("--threads", type=int, default=0, help="torch threads of each run (default: torch's choice)")
    p.add_argument("--no-export", action="store_true", help="skip the export and reopen round trips")
    p.add_argument("--tmp", default=None, help="folder for the scenes and results (default: the system's)")
    p.add_argument("--no-warmup", action="store_true", help="no untimed tiny run before the first size")
    p.add_argument("--lod", nargs="+", choices=("auto", "on", "off"), default=["auto"],
                   help="each size with the level of detail auto (the engine's default), on and/or off (default "
                        "auto; the RESULT line is of the first)")
    p.add_argument("--lod-pixels", type=float, nargs="+", default=[None],
                   help="the level of detail's cell sizes to run (default: the engine's); each with --lod on")
    p.add_argument("--shuffle", action="store_true",
                   help="each capture's rows written in a random order (a real file's order is not spatial)")
    args = p.parse_args(argv)
    if not args.source.exists():
        raise SystemExit(f"no capture at {args.source} (../shared/data absent? give --source)")
    print(f"engine scale: {cpu_description()}, {os.cpu_count()} cores; {args.preset} after "
          f"{args.style.name if args.style else 'the bundled painting'}, capture {args.source.name}", flush=True)
    source, _ = load_scene(args.source)
    rows = []
    with tempfile.TemporaryDirectory(dir=args.tmp) as tmp:
        folder = Path(tmp)
        if not args.no_warmup:
            warm = run_stylize(None, folder / "warmup.ply", args, smoke=True)
            print(f"warm-up (untimed): {warm['wall_seconds']:.0f} s", flush=True)
        for n in args.sizes:
            scene_path = folder / f"capture_{n}.ply"
            scene = densify(source, n)
            if args.shuffle:
                scene = scene.subset(np.random.default_rng(n).permutation(scene.count))
            save_scene(scene, scene_path)
            del scene
            runs = [(lod, px) for lod in args.lod for px in (args.lod_pixels if lod != "off" else [None])]
            for lod, px in runs:
                out = folder / f"out_{n}_{lod}_{px}.ply"
                record = run_stylize(scene_path, out, args, lod=lod, lod_pixels=px)
                row = figures(record)
                if not args.no_export:
                    row["exports"] = export_round_trips(out, folder)
                rows.append(row)
                print(f"{n:,} (lod {_lod_label(row)}): {row['seconds']:.0f} s, peak {row['peak'] / 2**30:.2f} GiB "
                      f"({row['bytes_per_gaussian']:,.0f} bytes a Gaussian)", flush=True)
            scene_path.unlink()
    print_tables(rows)
    print(result_line(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
