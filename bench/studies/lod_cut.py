"""How many parents the level of detail's cut holds at 256 / 512 / 1024 px, and how close its render is to the whole
capture's at that width (PSNR over the run's training views), per capture size (``bench/densify.py``'s captures from a
real one, optionally shuffled: a real file's order is not spatial).

    .venv/bin/python bench/studies/lod_cut.py --sizes 152746,1200000 --widths 256 512 1024
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
for path in (ROOT, ROOT / "bench"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

import torch  # noqa: E402
from densify import densify  # noqa: E402

from gstyle_core.engine.view_choice import choose_views  # noqa: E402
from gstyle_core.fit.ssim import psnr  # noqa: E402
from gstyle_core.lod import build_cut  # noqa: E402
from gstyle_core.scene_images import load_scene_and_cameras, render_scene_image  # noqa: E402

DEFAULT_SOURCE = ROOT.parent / "shared" / "data" / "scenes" / "playcanvas" / "biker.spz"


def measure(scene, cameras, width: int, target_px: float, views: int, size_factor: float = 1.0) -> dict:
    """The cut of ``scene`` at ``width`` and its render against the whole scene's on ``views`` of the cameras."""
    t0 = time.perf_counter()
    cut = build_cut(scene, cameras, width, target_px, size_factor=size_factor)
    seconds = time.perf_counter() - t0
    picks = sorted({int(i * len(cameras) / views) for i in range(views)})
    scores = []
    for i in picks:
        cam = cameras[i].resized_to_width(width)
        whole, parents = (torch.from_numpy(render_scene_image(s, cam, sh_degree=0)) for s in (scene, cut.parents))
        scores.append(psnr(whole, parents))
    return {"parents": cut.parent_count, "merged": int(cut.merged.sum()), "seconds": seconds,
            "psnr": float(np.mean(scores)), "psnr_min": float(np.min(scores))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", type=Path, default=DEFAULT_SOURCE)
    ap.add_argument("--sizes", default="152746,1200000")
    ap.add_argument("--widths", type=int, nargs="+", default=[256, 512, 1024])
    ap.add_argument("--target-px", type=float, nargs="+", default=[1.0])
    ap.add_argument("--size-factor", type=float, nargs="+", default=[1.0],
                    help="a Gaussian joins a cell when its 1σ diameter is at most this × the cell")
    ap.add_argument("--views", type=int, default=4, help="training views the PSNR is measured on")
    ap.add_argument("--shuffle", action="store_true", help="the densified capture's rows in a random order")
    args = ap.parse_args(argv)
    source, _report, cams = load_scene_and_cameras(str(args.source), None)
    cameras = [cams.cameras[i] for i in choose_views(list(cams.cameras), 16)]
    print("| Gaussians | width | cell px | size factor | parents | parents / Gaussians | merged parents | cut s | "
          "PSNR dB (min) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in (int(s) for s in args.sizes.split(",")):
        scene = densify(source, n) if n != source.count else source.with_sh_degree(0)
        if args.shuffle:
            scene = scene.subset(np.random.default_rng(1).permutation(scene.count))
        for width in args.widths:
            for target, factor in [(t, f) for t in args.target_px for f in args.size_factor]:
                m = measure(scene, cameras, width, target, args.views, factor)
                print(f"| {n:,} | {width} | {target:g} | {factor:g} | {m['parents']:,} | {m['parents'] / n:.3f} | "
                      f"{m['merged']:,} | {m['seconds']:.1f} | {m['psnr']:.2f} ({m['psnr_min']:.2f}) |", flush=True)
    print("RESULT done=1")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
