"""Style against structure on scenes without photos: a sweep of settings over captures × paintings.

Each point runs ``gstyle stylize`` (the same engine, preset and evaluation) and records how much of the painting
arrived (NNFM drop on the evaluation views) and how much of the scene survived (edge correlation, ``structure``).

    python bench/studies/strokes_sweep.py --scenes demo,fountain,biker --styles starry,mandelbrot,wave \\
        --variants "base:" "s2:strength=2" --jobs 1 --csv out/strokes.csv

A variant is ``name:key=value,key=value`` over ``StylizeSettings`` fields (``lambda_nnfm``, ``strength``,
``epochs``, ``optimizer``, ...) plus ``preset`` and ``scene_kind``. ``--jobs N`` runs N points at once in spawned
processes with ``--threads`` torch/numba threads each (times are then per process, not comparable with a quiet
2-core run). Prints a table per variant and ``RESULT``: the variant with the largest mean NNFM drop among those
whose worst structure is at least ``--min-structure``.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCENES = {"demo": None, "fountain": "scenes/splat/winter_fountain.cropped.splat",
          "biker": "scenes/playcanvas/biker.spz", "lastchance": "scenes/splat/lastchance.splat",
          "guitar": "scenes/playcanvas/guitar.compressed.ply"}
STYLES = {"starry": "styles/starry_night_vangogh.jpg", "mandelbrot": "styles/mandelbrot_color.png",
          "wave": "styles/great_wave_hokusai.jpg", "scream": "styles/the_scream_munch.jpg",
          "kandinsky": "styles/extra_composition_vii_kandinsky.jpg", "udnie": "styles/extra_udnie_picabia.jpg"}
FLOAT_KEYS = {"strength", "lambda_clip", "lambda_nnfm", "lambda_content", "lambda_tv", "epochs", "lr_start", "lr_end",
              "split_rate", "style_scale"}
INT_KEYS = {"min_steps", "views_per_step", "working_width", "max_views", "refit_iterations", "preprocess_rounds",
            "seed"}


def parse_variant(text: str) -> tuple[str, dict]:
    """``name:key=value,...`` → (name, overrides)."""
    name, _, body = text.partition(":")
    out: dict = {}
    for item in filter(None, body.split(",")):
        key, _, value = item.partition("=")
        out[key] = float(value) if key in FLOAT_KEYS else int(value) if key in INT_KEYS else value
    return name, out


def find_file(data: Path, table: dict, key: str) -> str | None:
    """Path of a named scene/style under ``data`` (or the file's own name there, for a flat copy)."""
    rel = table[key]
    if rel is None:
        return None
    for candidate in (data / rel, data / Path(rel).name):
        if candidate.exists():
            return str(candidate)
    raise SystemExit(f"{key}: {rel} not found under {data}")


def run_point(job: tuple) -> dict:
    """One stylization with evaluation (runs in a worker process)."""
    scene, style, variant, overrides, threads = job
    os.environ.setdefault("NUMBA_NUM_THREADS", str(threads))
    import torch

    torch.set_num_threads(threads)
    sys.path.insert(0, str(HERE.parents[1]))
    from gstyle_core.engine.build import BuildRequest, build_stylizer
    from gstyle_core.engine.run_figures import evaluate_run

    o = dict(overrides)
    request = BuildRequest(scene=scene, style=style, preset=o.pop("preset", "preview"),
                           scene_kind=o.pop("scene_kind", "auto"), overrides=o)
    t0 = time.perf_counter()
    engine, input_scene, _report, _cams, style_img = build_stylizer(request)
    engine.run()
    seconds = time.perf_counter() - t0
    q = evaluate_run(engine, input_scene, style_img)
    before, after = q.pop("images")
    return {"variant": variant, "scene": Path(scene).name if scene else "demo", "style": Path(style).stem,
            "nnfm_drop": round(q["nnfm_drop"], 4), "structure": round(q["structure"], 4),
            "nnfm_before": round(q["initial"]["nnfm"], 4), "nnfm_after": round(q["final"]["nnfm"], 4),
            "seconds": round(seconds, 1), "stylize_seconds": round(engine.timings.get("stylize", 0.0), 1),
            "steps": engine.stylize_steps, "gaussians": engine.gaussian_count, "_after": after}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(HERE.parents[2] / "shared" / "data"))
    ap.add_argument("--scenes", default="demo,fountain,biker")
    ap.add_argument("--styles", default="starry,mandelbrot,wave")
    ap.add_argument("--variants", nargs="+", default=["base:"])
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--min-structure", type=float, default=0.5)
    ap.add_argument("--csv", default="out/strokes_sweep.csv")
    ap.add_argument("--images", default="", help="folder for each point's after-render PNG (none by default)")
    a = ap.parse_args(argv)
    data = Path(a.data)
    variants = [parse_variant(v) for v in a.variants]
    jobs = [(find_file(data, SCENES, sc), find_file(data, STYLES, st), name, ov, a.threads)
            for name, ov in variants for sc in a.scenes.split(",") for st in a.styles.split(",")]
    rows: list[dict] = []
    Path(a.csv).parent.mkdir(parents=True, exist_ok=True)
    if a.jobs > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(a.jobs, maxtasksperchild=1) as pool:
            results = pool.imap_unordered(run_point, jobs)
            for row in results:
                rows.append(_report(row, a.images))
    else:
        for job in jobs:
            rows.append(_report(run_point(job), a.images))
    keys = [k for k in rows[0] if not k.startswith("_")]
    with open(a.csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    print(f"\n{'variant':<14} {'mean drop':>9} {'min drop':>8} {'mean struct':>11} {'min struct':>10} {'max s':>6}")
    best = None
    for name, _ in variants:
        rs = [r for r in rows if r["variant"] == name]
        drops, structs = [r["nnfm_drop"] for r in rs], [r["structure"] for r in rs]
        mean_drop = sum(drops) / len(drops)
        print(f"{name:<14} {100 * mean_drop:8.1f}% {100 * min(drops):7.1f}% {sum(structs) / len(structs):11.3f} "
              f"{min(structs):10.3f} {max(r['seconds'] for r in rs):6.0f}")
        if min(structs) >= a.min_structure and (best is None or mean_drop > best[1]):
            best = (name, mean_drop)
    print(f"RESULT points={len(rows)} best={best[0] if best else 'none'} "
          f"best_mean_drop={100 * best[1] if best else 0:.1f}%")
    return 0


def _report(row: dict, images: str) -> dict:
    print(f"{row['variant']:<14} {row['scene']:<34} {row['style']:<26} drop {100 * row['nnfm_drop']:5.1f}% "
          f"structure {row['structure']:.3f} {row['seconds']:6.1f} s ({row['steps']} steps)", flush=True)
    if images:
        from PIL import Image

        Path(images).mkdir(parents=True, exist_ok=True)
        name = f"{row['variant']}_{Path(row['scene']).stem}_{row['style']}.png".replace(" ", "_")
        Image.fromarray((row["_after"].clip(0, 1) * 255).astype("uint8")).save(Path(images) / name)
    return row


if __name__ == "__main__":
    raise SystemExit(main())
