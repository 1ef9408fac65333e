"""What accuracy costs in time: sweep the stylization's speed/quality knobs, measure both, mark the Pareto front.

    .venv/bin/python bench/tradeoff.py [--fern out/fern.ply] [--groups demo:starry,...] [--quick]

Each point is one full stylization (the real ``Stylizer`` driven to the end, as ``gstyle stylize`` does) with the
sweep's base (``BASE``: the 6-epoch preview the sweep was first measured with) and one knob changed: working
resolution, epochs, pre-processing rounds (0, the preset's 1, the paper's 5 forward-facing / 10 for 360°),
colour-gradient splitting off, culling of Gaussians no camera sees off, VGG on whole frames instead of the scene's
box (``crop_to_scene`` off; photos are whole frames anyway), the ``balanced`` preset, the style strength (0.3, 1,
3, 10 on the preview preset as shipped: ``STRENGTH_SWEEP``, every group), and with
``--with-slow`` VGG in bf16 (channels_last) and the pure-torch reference rasterizer for ground truth and refits.
Scenes: the bundled demo (360°), the fern (forward-facing; fit it first with
``gstyle fit ../shared/data/scenes/llff_fern --out out/fern.ply``) and, from ``../shared/data`` when present, the 360°
captures ``biker`` and ``winter`` (winter_fountain). ``--sweep scale`` runs ``SCALE_SWEEP`` instead on every group:
the broad-strokes term on and off at stroke sizes 0.5, 1 and 2, and the balanced and final presets, as shipped.

Quality is measured on 3 fixed evaluation views at one width (256 px) for every point:
- ``nnfm_drop``: 1 − NNFM distance to the style after / before (coverage-weighted; higher = more stylized),
- ``structure``: correlation of the edge maps of the before/after renders over the scene (how much survived),
- ``content``: VGG relu3 MSE to the input scene's renders (lower = more of the scene kept),
- ``colour``: distance of RGB mean/covariance to the style's,
- ``consistency``: reprojection error between each evaluation view and a nearby view (rendered depth;
  ``consistency_input`` is the same for the input scene, the floor of the measure; the nearby view is the
  evaluation camera moved sideways by 3 % of the scene's median depth),
- ``preprocess_psnr``: PSNR of the pre-processed scene against the ground truth on the training views,
- ``coarse_added`` / ``coarse_painting`` / ``coarse_ratio``: the texture-scale figure (``style/texture_scale.py``):
  the coarse band's share of what stylization added, the painting's own at its matched size, and their ratio.
Writes ``docs/tradeoff.csv`` and ``docs/tradeoff.png`` (NNFM drop against time per scene/style, Pareto front =
among the points that keep the structure (≥ ``MIN_STRUCTURE``), no other point of the group is both faster and more
stylized) and prints ``RESULT points=N pareto=M`` last. ``--replot`` redraws both from the CSV, ``--table`` prints
the table of docs/tradeoffs.md from it.
``--merge --points "width 320,bf16 VGG" --with-slow`` re-measures only those points and keeps the other rows.
Run it on a quiet machine: the times are wall-clock seconds on this one.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import re
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gstyle_core.machine import set_torch_threads  # noqa: E402
from gstyle_core.pipeline.build import BuildRequest, build_stylizer  # noqa: E402
from gstyle_core.pipeline.consistency import nearby_camera, view_consistency  # noqa: E402
from gstyle_core.pipeline.view_choice import choose_views  # noqa: E402

SHARED = ROOT.parent / "shared" / "data"
SCENES: dict[str, tuple[str | None, str | None]] = {"demo": (None, None)}  # (scene, cameras); None = the demo
CAPTURES = {"biker": SHARED / "scenes" / "playcanvas" / "biker.spz",  # 360° captures, used when present
            "winter": SHARED / "scenes" / "splat" / "winter_fountain.cropped.splat"}
FERN_CAMERAS = SHARED / "scenes" / "llff_fern"  # photos + poses: the fern's ground truth
STYLES = {"starry": ROOT / "assets" / "styles" / "starry_night.jpg",
          "mandelbrot": SHARED / "styles" / "mandelbrot_color.png",
          "wave": SHARED / "styles" / "great_wave_hokusai.jpg"}
# The sweep's base point: the 6-epoch preview preset it was measured with (labelled "preview" in docs/tradeoff.csv).
# The preset itself became the "epochs 3" point once the front was known (docs/tradeoffs.md), so the base stays
# explicit here and every point below changes one knob of it.
BASE = {"epochs": 6.0, "min_steps": 60}
FULL_SWEEP = [
    ("preview", "preview", {}),
    ("width 128", "preview", {"working_width": 128}),
    ("width 256", "preview", {"working_width": 256}),
    ("epochs 3", "preview", {"epochs": 3.0, "min_steps": 30}),
    ("epochs 12", "preview", {"epochs": 12.0, "min_steps": 120}),
    ("no preprocess", "preview", {"preprocess_rounds": 0}),
    ("paper rounds", "preview", {"preprocess_rounds": "paper"}),
    ("no colour split", "preview", {"split_rate": 0.0}),
    ("no culling", "preview", {"cull_unseen": False}),
    ("whole frames", "preview", {"crop_to_scene": False}),  # VGG on whole frames, not only the scene's box
    ("balanced", "balanced", {}),
    ("no CLIP term", "preview", {"lambda_clip": 0.0}),  # λ 0: the term (here its coarse-VGG substitute) never runs
]
SLOW_POINTS = [  # --with-slow: measured once (see docs/tradeoffs.md), left out of the default sweep for its time
    ("width 320", "preview", {"working_width": 320}),
    ("bf16 VGG", "preview", {"precision": "bf16"}),  # measured on a CPU without AVX512-BF16: 5-13x slower VGG there;
    # about 2x faster on one with it (bench/precision.py)
    ("reference raster", "preview", {"raster_backend": "reference"}),  # pure-torch rasterizer for GT and refits
]
# Style strength on the preview preset as shipped ("shipped": no BASE; on 360° scenes the calibrated defaults).
STRENGTH_SWEEP = [("as shipped", "shipped", {})] + [
    (f"strength {s:g}", "shipped", {"strength": s}) for s in (0.3, 3.0, 10.0)]
FULL_SWEEP += STRENGTH_SWEEP
# Style at every scale (issue #23): the broad-strokes term and the coherent strokes (colour field) each on/off at
# three stroke sizes, and the higher presets, all as shipped (on 360° captures the calibrated defaults).
SCALE_SWEEP = [(f"stroke {s:g}{suffix}", "shipped", {"style_scale": s, **extra})
               for suffix, extra in (("", {}), (" no broad strokes", {"lambda_multiscale": 0.0}),
                                     (" no coherent strokes", {"colour_field": False}))
               for s in (0.5, 1.0, 2.0)]
SCALE_SWEEP += [("balanced as shipped", "balanced", {}), ("final as shipped", "final", {}),
                ("broad strokes 100", "shipped", {"lambda_multiscale": 100.0})]  # half the 360° default
SHORT_SWEEP = [p for p in FULL_SWEEP if p[0] in ("preview", "width 128", "width 256", "epochs 3", "epochs 12")]
SHORT_SWEEP += STRENGTH_SWEEP
QUICK_SWEEP = [("preview", "preview", {"epochs": 1.0, "min_steps": 4, "max_views": 4, "refit_iterations": 5}),
               ("width 128", "preview", {"epochs": 1.0, "min_steps": 4, "max_views": 4, "refit_iterations": 5,
                                          "working_width": 128})]
POINT_PRECISION = "fp32"  # every point but "bf16 VGG" (``--precision``): the CSV's rows were measured in fp32
EVAL_WIDTH = 256
PICTURE_WIDTH = 1024  # --pictures: one view per point at this width (strokes can be judged; the gallery's at 512)
MIN_STRUCTURE = 0.5  # edge correlation below which the scene is considered lost (issue #14's threshold)
NEARBY_SHIFT = 0.03  # consistency: the second view is moved sideways by 3 % of the scene's median depth


def median_depth(scene, camera) -> float:
    """Median camera-space depth of the Gaussians in front of ``camera``."""
    pts = scene.means @ camera.world_to_cam[:3, :3].T + camera.world_to_cam[:3, 3]
    z = pts[:, 2][pts[:, 2] > 0]
    return float(np.median(z)) if z.size else 1.0


def psnr(engine) -> float:
    """PSNR of the current geometry with c_gt against the ground truth, over the training views."""
    from gstyle_core.fit.model import render_params

    errors = []
    with torch.no_grad():
        for cam, gt in zip(engine.cameras, engine.gt_images, strict=True):
            img = render_params(engine.params, cam, sh_degree=0).image
            errors.append(float(((img - gt) ** 2).mean()))
    return float(-10 * math.log10(max(np.mean(errors), 1e-12)))


def picture_name(label: str) -> str:
    """A point's label as a file name: "stroke 0.5 no broad strokes" -> "stroke_0.5_no_broad_strokes"."""
    return re.sub(r"[^\w.]+", "_", label).strip("_")


def save_pictures(engine, scene_in, folder: Path, name: str, width: int = PICTURE_WIDTH) -> None:
    """The middle evaluation view of the input and of the stylized scene, ``width`` px wide, cropped to the scene:
    ``folder/<name>.png`` (stylized) and ``folder/input.png``; the gallery's picture (``bench/gallery.py``: input
    above, stylized below, three views 512 px wide) as ``folder/<name>_views.png``; the stylized scene as
    ``folder/<name>.ply``."""
    from gstyle_core.render_cli import before_after_picture, save_png, scene_rows

    cams = engine.full_cameras
    camera = cams[choose_views(cams, 3)[1 if len(cams) > 1 else 0]]
    stylized = engine.stylized_scene()
    before, after = scene_rows([scene_in, stylized], [camera], 1, width)
    folder.mkdir(parents=True, exist_ok=True)
    save_png(folder / f"{name}.png", after)
    save_png(folder / "input.png", before)
    save_png(folder / f"{name}_views.png", before_after_picture(scene_in, stylized, cams, n_views=3, width=512))
    from gstyle_core.io.saver import save_scene

    save_scene(stylized, folder / f"{name}.ply")  # to look at it again at any size (gstyle render, the studio)


def run_point(scene: str | None, style: Path, preset: str, overrides: dict, cameras: str | None = None,
              pictures: tuple[Path, str] | None = None) -> dict:
    """One stylization with ``overrides``; wall time per phase and the quality figures (``pictures`` = (folder,
    name): also the pictures of ``save_pictures``)."""
    from gstyle_core.pipeline.run_figures import evaluate_run, evaluation_cameras

    kw = {**BASE, **overrides} if preset == "preview" else dict(overrides)
    kw = {"precision": POINT_PRECISION, **kw}
    preset = "preview" if preset == "shipped" else preset
    if kw.get("preprocess_rounds") == "paper":
        kw.pop("preprocess_rounds")
        paper = True
    else:
        paper = False
    t0 = time.perf_counter()
    engine, scene_in, _, _, style_img = build_stylizer(
        BuildRequest(scene=scene, style=str(style), cameras=cameras, preset=preset, overrides=kw))
    if paper:
        engine.settings.preprocess_rounds = 5 if engine.settings.scene_kind == "forward" else 10
    build_s = time.perf_counter() - t0
    pre_psnr = float("nan")
    phase_wall: dict[str, float] = {}
    while not engine.done:
        t = time.perf_counter()
        rep = engine.step()
        phase_wall[rep.phase] = phase_wall.get(rep.phase, 0.0) + time.perf_counter() - t
        if rep.phase == "colour_match" and math.isnan(pre_psnr):
            pre_psnr = psnr(engine)
    total = time.perf_counter() - t0
    q = evaluate_run(engine, scene_in, style_img, n_views=3, width=EVAL_WIDTH)
    q.pop("images")
    if pictures is not None:
        save_pictures(engine, scene_in, *pictures)
    eval_cams = evaluation_cameras(engine, 3, EVAL_WIDTH)
    pairs = [(c, nearby_camera(c, NEARBY_SHIFT * median_depth(scene_in, c))) for c in eval_cams]
    return {
        "seconds": total, "build_s": build_s, **{f"s_{k}": v for k, v in phase_wall.items()},
        "gaussians": engine.gaussian_count, "nnfm_before": q["initial"]["nnfm"], "nnfm_after": q["final"]["nnfm"],
        "nnfm_drop": 1 - q["final"]["nnfm"] / max(q["initial"]["nnfm"], 1e-12), "content": q["final"]["content"],
        "structure": q["structure"],
        "colour": q["final"]["colour"], "consistency": view_consistency(engine.stylized_scene(), pairs),
        "consistency_input": view_consistency(scene_in, pairs), "preprocess_psnr": pre_psnr,
        "working_width": engine.settings.working_width, "steps": engine.global_step,
        "coarse_added": q["texture_scale"]["added"]["coarse"],
        "coarse_painting": q["texture_scale"]["painting"]["coarse"],
        "coarse_ratio": q["texture_scale"]["coarse_ratio"],
    }


def keeps_structure(point: dict) -> bool:
    """Whether the run kept the scene's structure (edge correlation ≥ MIN_STRUCTURE; rows without it count)."""
    value = point.get("structure")
    return value in (None, "") or float(value) >= MIN_STRUCTURE


def pareto(points: list[dict]) -> list[bool]:
    """True for points that keep the structure and that no such point beats on both time (lower) and NNFM drop
    (higher): a stronger style bought by losing the scene is not a trade-off."""
    kept = [p for p in points if keeps_structure(p)]
    flags = []
    for p in points:
        dominated = any(q is not p and q["seconds"] <= p["seconds"] and q["nnfm_drop"] >= p["nnfm_drop"]
                        and (q["seconds"] < p["seconds"] or q["nnfm_drop"] > p["nnfm_drop"]) for q in kept)
        flags.append(keeps_structure(p) and not dominated)
    return flags


def plot(rows: list[dict], path: Path) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed (pip install -e .[bench]): no plot")
        return False
    groups = sorted({r["group"] for r in rows})
    cols = min(2, len(groups))
    nrows = -(-len(groups) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(6.0 * cols, 4.2 * nrows), squeeze=False)
    for ax in axes.flat[len(groups):]:
        ax.set_visible(False)
    for ax, g in zip(axes.flat, groups, strict=False):
        pts = [r for r in rows if r["group"] == g]
        kept = [r for r in pts if keeps_structure(r)]
        lost = [r for r in pts if not keeps_structure(r)]
        ax.scatter([r["seconds"] for r in kept], [100 * r["nnfm_drop"] for r in kept], c="tab:blue", s=22)
        if lost:
            ax.scatter([r["seconds"] for r in lost], [100 * r["nnfm_drop"] for r in lost], c="tab:gray", s=30,
                       marker="x", label=f"structure < {MIN_STRUCTURE:g}")
        front = sorted((r for r in pts if r["pareto"]), key=lambda r: r["seconds"])
        ax.plot([r["seconds"] for r in front], [100 * r["nnfm_drop"] for r in front], "-o", c="tab:red", ms=5,
                label="Pareto front")
        for r in pts:
            ax.annotate(r["label"], (r["seconds"], 100 * r["nnfm_drop"]), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
        ax.set_title(g)
        ax.set_xlabel("wall time (s, 2 CPU cores)")
        ax.set_ylabel("NNFM distance to the style: drop (%)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    from gstyle_core.atomic import atomic_write

    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    return True


def write_outputs(rows: list[dict], out: Path) -> None:
    """Mark each group's Pareto front, write the CSV and the plot (after every point: nothing is lost)."""
    from gstyle_core.atomic import atomic_write_text

    for g in {r["group"] for r in rows}:
        pts = [r for r in rows if r["group"] == g]
        for r, flag in zip(pts, pareto(pts), strict=True):
            r["pareto"] = flag
    fields = sorted({k for r in rows for k in r}, key=lambda k: (k not in ("group", "label", "pareto"), k))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields)
    writer.writeheader()
    for r in rows:
        writer.writerow({k: (f"{v:.5g}" if isinstance(v, float) else v) for k, v in r.items()})
    atomic_write_text(out.with_suffix(".csv"), buf.getvalue())
    plot(rows, out.with_suffix(".png"))


def markdown_rows(rows: list[dict]) -> list[str]:
    """The rows of the table in docs/tradeoffs.md (one per point) from the CSV's rows."""
    def num(r: dict, key: str, fmt: str) -> str:
        v = r.get(key)
        return "—" if v in (None, "") else format(float(v), fmt)

    out = []
    for r in rows:
        psnr = r.get("preprocess_psnr")
        no_change = psnr in (None, "") or float(psnr) >= 100  # no pre-processing: PSNR clamped at 120 dB
        psnr_text = "no change" if no_change else f"{float(psnr):.1f} dB"
        out.append(f"| {r['group']} | {r['label']} | {float(r['seconds']):.0f} | {100 * float(r['nnfm_drop']):.1f} % | "
                   f"{num(r, 'structure', '.2f')} | {num(r, 'content', '.1f')} | {num(r, 'colour', '.3f')} | "
                   f"{num(r, 'consistency', '.4f')} ({num(r, 'consistency_input', '.4f')}) | {psnr_text} | "
                   f"{num(r, 'coarse_ratio', '.2f')} | {'yes' if r.get('pareto') in (True, 'True') else ''} |")
    return out


def read_rows(path: Path, groups: set[str], labels: set[str] | None = None) -> list[dict]:
    """Rows of an earlier CSV that this run does not re-measure: those outside ``groups``, or (with ``labels``)
    whose label is not among them (numbers back to floats; the Pareto flags are recomputed)."""
    if not path.is_file():
        return []
    rows = []
    with path.open(newline="") as fh:
        for r in csv.DictReader(fh):
            if r["group"] in groups and (labels is None or r["label"] in labels):
                continue
            row: dict = {}
            for k, v in r.items():
                if k in ("group", "label", "pareto") or v == "":
                    row[k] = v if k != "pareto" else v == "True"
                    continue
                try:
                    row[k] = int(v) if k in ("gaussians", "steps", "working_width") else float(v)
                except ValueError:
                    row[k] = v
            rows.append({k: v for k, v in row.items() if v != ""})
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fern", default=str(ROOT / "out" / "fern.ply"), help="fitted fern scene (gstyle fit)")
    p.add_argument("--groups", default="demo:starry,demo:mandelbrot,fern:starry,fern:mandelbrot",
                   help="scene:style pairs; the first gets the full sweep, the others a short one")
    p.add_argument("--quick", action="store_true", help="two tiny points on the demo (a smoke test, minutes)")
    p.add_argument("--sweep", choices=("knobs", "scale"), default="knobs",
                   help="knobs: the full sweep on the first group, a short one on the others; scale: SCALE_SWEEP on "
                        "every group")
    p.add_argument("--with-slow", action="store_true", help="also the width-320 and bf16 points of the first group")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--pictures", default=None, metavar="DIR",
                   help=f"also save one {PICTURE_WIDTH}-px view per point: DIR/<scene>_<style>/<label>.png")
    p.add_argument("--out", default=str(ROOT / "docs" / "tradeoff"), help="CSV/PNG path without suffix")
    p.add_argument("--merge", action="store_true",
                   help="keep the rows already in the CSV that this run does not re-measure")
    p.add_argument("--points", default=None,
                   help="comma-separated point labels to run (of the sweep, with --with-slow its slow points too)")
    p.add_argument("--table", action="store_true", help="print the CSV as docs/tradeoffs.md's table and exit")
    p.add_argument("--replot", action="store_true", help="recompute the Pareto flags and the plot from the CSV")
    args = p.parse_args()
    if args.replot:
        rows = read_rows(Path(args.out).with_suffix(".csv"), set())
        write_outputs(rows, Path(args.out))
        print(f"RESULT points={len(rows)} pareto={sum(r['pareto'] for r in rows)}")
        return
    if args.table:
        with Path(args.out).with_suffix(".csv").open(newline="") as fh:
            print("\n".join(markdown_rows(list(csv.DictReader(fh)))))
        return
    set_torch_threads(args.threads)
    scenes = dict(SCENES)
    if Path(args.fern).is_file():
        scenes["fern"] = (args.fern, str(FERN_CAMERAS))
    scenes.update({name: (str(path), None) for name, path in CAPTURES.items() if path.is_file()})
    out = Path(args.out)
    groups = [g.split(":") for g in args.groups.split(",")] if not args.quick else [["demo", "starry"]]
    wanted = None if args.points is None else {x.strip() for x in args.points.split(",")}
    if not args.quick:  # the first stylization of a process pays imports, weight loading and kernel loading
        label, preset, overrides = QUICK_SWEEP[0]
        t0 = time.perf_counter()
        run_point(None, STYLES["starry"], preset, overrides)
        print(f"warm-up (not recorded): {time.perf_counter() - t0:.1f} s", flush=True)
    names = {f"{a} / {b}" for a, b in groups}
    rows: list[dict] = read_rows(out.with_suffix(".csv"), names, wanted) if args.merge else []
    for gi, (scene_name, style_name) in enumerate(groups):
        if scene_name not in scenes:
            fit = "fit it first: gstyle fit ../shared/data/scenes/llff_fern --out out/fern.ply"
            hint = (fit if scene_name == "fern"
                    else f"not in {SHARED}" if scene_name in CAPTURES else "unknown scene name")
            print(f"skip {scene_name}: not found ({hint})")
            continue
        if not STYLES[style_name].is_file():
            print(f"skip {style_name}: {STYLES[style_name]} not found")
            continue
        sweep = QUICK_SWEEP if args.quick else (FULL_SWEEP if gi == 0 else SHORT_SWEEP)
        if args.sweep == "scale" and not args.quick:
            sweep = SCALE_SWEEP
        if gi == 0 and args.with_slow and not args.quick:
            sweep = sweep + SLOW_POINTS
        for label, preset, overrides in sweep:
            if wanted is not None and label not in wanted:
                continue
            scene_path, cameras = scenes[scene_name]
            shots = None if args.pictures is None else (Path(args.pictures) / f"{scene_name}_{style_name}",
                                                         picture_name(label))
            res = run_point(scene_path, STYLES[style_name], preset, overrides, cameras=cameras, pictures=shots)
            row = {"group": f"{scene_name} / {style_name}", "label": label, **res}
            rows.append(row)
            print(f"{row['group']:<20} {label:<16} {res['seconds']:7.1f} s  NNFM drop {100 * res['nnfm_drop']:5.1f} %"
                  f"  structure {res['structure']:.2f}"
                  f"  content {res['content']:7.2f}  colour {res['colour']:.3f}  consistency {res['consistency']:.4f}"
                  f" (input {res['consistency_input']:.4f})  preprocess PSNR {res['preprocess_psnr']:.2f} dB"
                  f"  coarse ratio {res['coarse_ratio']:.2f}",
                  flush=True)
            write_outputs(rows, out)
    print(f"wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")
    print(f"RESULT points={len(rows)} pareto={sum(r['pareto'] for r in rows)}")


if __name__ == "__main__":
    main()
