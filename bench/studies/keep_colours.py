"""Keep colours: which colour-preservation variant reads better (issue #15), and what it costs the painting.

Variants, each a full ``gstyle stylize`` run (same engine, preset, evaluation views):

* ``plain``   — no keep colours: the painting's colours (full colour match before and after);
* ``lum``     — keep colours as shipped: luminance-only colour match, networks on luminance (Gatys et al. 2016 (a)),
  per-Gaussian chroma of c_gt restored after every step ((b));
* ``restore`` — keep colours with colour networks: luminance-only colour match and the chroma restore only ((b)).

Measured on the evaluation views (3 views at 256 px, covered pixels): ``lumNNFM`` the NNFM distance of the render's
luminance to the painting's luminance, before → after and its drop (how much of the painting's light/dark pattern
arrived); ``structure`` (edge correlation, as ``gstyle stylize`` prints); ``ΔIQ`` the mean distance of each covered
pixel's chroma (I, Q) from the input render's (0: hues kept); ``IQ→paint`` the distance of the mean chroma from the
painting's. Writes ``OUT_DIR/keep_<variant>.png`` (before above, after below) and prints one row per variant and a
``RESULT`` line.

    python bench/studies/keep_colours.py [--scene SCENE] [--style IMAGE] [--variants plain,lum,restore] [--out-dir out]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def luminance_nnfm(vgg, style: np.ndarray, renders: list[np.ndarray], alphas: list[np.ndarray]) -> float:
    """NNFM distance of the renders' luminance to the painting's luminance, weighted by coverage."""
    from gstyle_core.engine.evaluate import Evaluator
    from gstyle_core.style.keep_colours import grey

    ev = Evaluator(vgg, grey(style), 256)
    return ev.measure([grey(r) for r in renders], [grey(r) for r in renders], alphas)["nnfm"]


def run_variant(name: str, scene: str | None, style_path: str | None, preset: str) -> dict:
    """One stylization and its measurements."""
    from gstyle_core.engine.build import BuildRequest, build_stylizer
    from gstyle_core.engine.objective import StyleObjective
    from gstyle_core.engine.run_figures import evaluate_run, evaluation_cameras
    from gstyle_core.scene_images import render_scene_image
    from gstyle_core.style.keep_colours import chroma

    StyleObjective.luminance_networks = name != "restore"
    request = BuildRequest(scene=scene, style=style_path, preset=preset, overrides={"keep_colours": name != "plain"})
    t0 = time.perf_counter()
    engine, input_scene, _report, _cams, style = build_stylizer(request)
    engine.run()
    seconds = time.perf_counter() - t0
    q = evaluate_run(engine, input_scene, style)
    before_img, after_img = q.pop("images")
    cams = evaluation_cameras(engine)
    before, alpha = zip(*(render_scene_image(input_scene, c, with_alpha=True) for c in cams), strict=True)
    after = [render_scene_image(engine.stylized_scene(), c) for c in cams]
    vgg = engine.objective.vgg
    lum_before = luminance_nnfm(vgg, style, list(before), list(alpha))
    lum_after = luminance_nnfm(vgg, style, after, list(alpha))
    covered = [np.asarray(a) > 0.5 for a in alpha]
    iq_before = np.concatenate([chroma(b[m]) for b, m in zip(before, covered, strict=True)])
    iq_after = np.concatenate([chroma(a[m]) for a, m in zip(after, covered, strict=True)])
    iq_paint = chroma(style.reshape(-1, 3)).mean(0)
    return {"variant": name, "seconds": seconds, "lum_before": lum_before, "lum_after": lum_after,
            "lum_drop": 1 - lum_after / max(lum_before, 1e-12), "structure": q["structure"],
            "nnfm_drop": q["nnfm_drop"], "d_iq": float(np.linalg.norm(iq_after - iq_before, axis=1).mean()),
            "iq_to_paint": float(np.linalg.norm(iq_after.mean(0) - iq_paint)),
            "iq_input_to_paint": float(np.linalg.norm(iq_before.mean(0) - iq_paint)),
            "picture": np.concatenate([before_img, after_img], axis=0)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scene", default=None, help="scene file (default: the bundled demo)")
    p.add_argument("--style", default=None, help="painting (default: the bundled one)")
    p.add_argument("--preset", default="preview")
    p.add_argument("--variants", default="plain,lum,restore")
    p.add_argument("--out-dir", default="out")
    p.add_argument("--threads", type=int, default=None)
    args = p.parse_args()

    from gstyle_core.machine import set_torch_threads
    from gstyle_core.scene_images import save_png

    if args.threads:
        set_torch_threads(args.threads)
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    print("| variant | wall | lumNNFM before → after (drop) | NNFM drop | structure | ΔIQ vs input | IQ→paint "
          "(input's) |")
    print("|---|---|---|---|---|---|---|")
    for name in args.variants.split(","):
        r = run_variant(name, args.scene, args.style, args.preset)
        save_png(out / f"keep_{name}.png", r.pop("picture"))
        rows.append(r)
        print(f"| {name} | {r['seconds']:.0f} s | {r['lum_before']:.3f} → {r['lum_after']:.3f} "
              f"({100 * r['lum_drop']:.0f} %) | {100 * r['nnfm_drop']:.0f} % | {r['structure']:.2f} | "
              f"{r['d_iq']:.3f} | {r['iq_to_paint']:.3f} ({r['iq_input_to_paint']:.3f}) |", flush=True)
    kept = [r for r in rows if r["variant"] != "plain"]
    if kept:
        best = max(kept, key=lambda r: r["lum_drop"])
        print(f"RESULT keep-colours variant with the largest luminance-pattern drop: {best['variant']} "
              f"({100 * best['lum_drop']:.0f} %, ΔIQ {best['d_iq']:.3f}, structure {best['structure']:.2f})")


if __name__ == "__main__":
    main()
