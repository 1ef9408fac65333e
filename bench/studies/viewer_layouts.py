"""The viewer's compact texture layout against its float32 one and against ``gstyle render``, on real captures.

For each scene (default: biker.spz, winter_fountain.cropped.splat, and a degree-3 SH .ply) and each of
``--views`` generated orbit views (``gstyle_core.cameras.generate``), headless EGL at ``--size``: the GL viewer's
image in the "compact" layout (half-float quaternions, scales, colours and SH) and in the "float32" one, 8-bit,
on black, with the exact depth order (so only the layout differs); the rasterizer's own render of the view (what
``gstyle render`` draws, its fast backend). Prints, per scene and view, the 8-bit |compact - float32| mean, 99.9th
percentile and maximum, the PSNR of each layout against the rasterizer, and the GL bytes a Gaussian of each
layout (``SplatRenderer.gl_memory``: geometry, colour layer, SH).

    .venv/bin/python bench/studies/viewer_layouts.py [--views 4] [--size 400x300] [SCENE ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import moderngl  # noqa: E402

from app.main import parse_size  # noqa: E402
from app.renderer_views import draw_views  # noqa: E402
from app.splat_data import LAYOUTS, scene_arrays  # noqa: E402
from gstyle_core.cameras.generate import generate_cameras  # noqa: E402
from gstyle_core.io import load_scene  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402
from gstyle_core.scene_images import render_scene_image  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "scenes"
SCENES = [DATA / "playcanvas" / "biker.spz", DATA / "splat" / "winter_fountain.cropped.splat",
          DATA / "ply_3dgs" / "kacytran1122_try_iter7000_point_cloud.ply"]


def psnr(image: np.ndarray, reference: np.ndarray) -> float:
    """PSNR (dB) of an 8-bit image against a [0, 1] float one."""
    mse = np.mean((image / 255.0 - np.clip(reference, 0.0, 1.0)) ** 2)
    return float(10 * np.log10(1.0 / max(mse, 1e-12)))


def compare(ctx: moderngl.Context, path: Path, args: argparse.Namespace) -> list[str]:
    """Table rows of one scene."""
    scene, _ = load_scene(path)
    cams = generate_cameras(scene.means, count=args.views, width=args.size[0], height=args.size[1]).cameras
    layer = "sh" if scene.sh_degree > 0 else "diffuse"
    arrays = scene_arrays(scene)
    results = {layout: draw_views(ctx, arrays, cams, layout, layer) for layout in LAYOUTS}
    per_gaussian = {layout: "/".join(f"{memory[k] / scene.count:.0f}" for k in ("geometry", "colours", "sh"))
                    for layout, (_, memory) in results.items()}
    rows = []
    for i, cam in enumerate(cams):
        compact, full = results["compact"][0][i], results["float32"][0][i]
        diff = np.abs(compact - full)
        reference = render_scene_image(scene, cam)
        rows.append(f"| {path.name} ({scene.count:,}, SH {scene.sh_degree}) | {cam.name} | {diff.mean():.4f} | "
                    f"{np.percentile(diff, 99.9):.0f} | {diff.max()} | {psnr(compact, reference):.2f} | "
                    f"{psnr(full, reference):.2f} | {per_gaussian['compact']} | {per_gaussian['float32']} |")
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenes", nargs="*", type=Path, default=SCENES)
    p.add_argument("--views", type=int, default=4)
    p.add_argument("--size", type=parse_size, default=(400, 300))
    args = p.parse_args()
    print(f"cpu: {cpu_description()}; {args.size[0]}x{args.size[1]}, exact depth order, on black")
    print("| scene (Gaussians, SH degree) | view | compact vs float32: mean | 99.9th pct | max | "
          "PSNR vs gstyle render, compact | float32 | GL B/G compact (geometry/colour/SH) | float32 |")
    print("|---|---|---|---|---|---|---|---|---|")
    ctx = moderngl.create_standalone_context(backend="egl", require=330)
    for path in args.scenes:
        if not path.is_file():
            print(f"| {path.name} | absent | | | | | | | |")
            continue
        compare(ctx, path, args)
    ctx.release()


if __name__ == "__main__":
    main()
