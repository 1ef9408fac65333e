"""``gstyle fit``: 3DGS optimisation from posed images, with a progress bar and train / held-out PSNR."""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from ..errors import GStyleError


def add_fit_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``gstyle fit``."""
    p.add_argument("scene_dir", help="folder with posed images (LLFF poses_bounds.npy, COLMAP sparse/0, cameras.json)")
    p.add_argument("--cameras", help="camera file or folder if not inside scene_dir")
    p.add_argument("--images", help="image folder (default: found beside the cameras, e.g. images_8)")
    p.add_argument("--iterations", type=int, default=1500, help="default fits fern (images_8) in < 15 min on 2 cores")
    p.add_argument("--width", type=int, default=None, help="train at this image width (default: the images' width)")
    p.add_argument("--holdout", type=int, default=8, help="hold out every N-th view for evaluation (0: none)")
    p.add_argument("--sh-degree", type=int, default=3)
    p.add_argument("--max-gaussians", type=int, default=80_000, help="cap on densification (speed)")
    p.add_argument("--backend", choices=["fast", "reference"], default="fast")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, help="output .ply")
    p.add_argument("--force", action="store_true", help="overwrite an existing output")


def fit_command(args: argparse.Namespace) -> int:
    """Run ``gstyle fit``."""
    import torch
    from tqdm import tqdm

    from ..atomic import atomic_write_text, refuse_overwrite
    from ..cameras import load_cameras
    from ..io import save_scene
    from .init import random_points_in_view, scene_from_points
    from .model import params_from_scene, scene_from_params
    from .strategy import DefaultStrategy
    from .trainer import FitConfig, Trainer, scene_scale

    refuse_overwrite(args.out, args.force)
    torch.manual_seed(args.seed)
    cams = load_cameras(args.cameras or args.scene_dir, image_dir=args.images)
    if not cams.has_images:
        raise GStyleError(f"no images found for the cameras in {args.scene_dir}; fitting needs photos")
    if args.width:
        cams = cams.scaled_to_width(args.width)
    train, test = cams.split_train_test(args.holdout) if args.holdout else (cams, None)
    train_images = train.load_images()
    test_images = test.load_images() if test is not None and test.cameras else []
    if cams.points is not None and len(cams.points) > 0:
        init = scene_from_points(cams.points, cams.point_colors, args.sh_degree)
        source = f"{len(cams.points)} sparse points"
    else:
        near = cams.near or 0.1
        far = cams.far or 10.0
        pts = random_points_in_view(train.cameras, 50_000, near, far, args.seed)
        init = scene_from_points(pts, None, args.sh_degree)
        source = "50000 random points (no sparse points found)"
    print(f"fit: {len(train.cameras)} training views, {len(test.cameras) if test else 0} held out, "
          f"{train.cameras[0].width}x{train.cameras[0].height}, init from {source}")
    params = params_from_scene(init)
    cfg = FitConfig(iterations=args.iterations, sh_degree=args.sh_degree, backend=args.backend, seed=args.seed,
                    sh_increase_every=max(1, args.iterations // 4))
    extent = scene_scale(train.cameras)
    strategy = DefaultStrategy(refine_start=min(500, args.iterations // 10), refine_stop=int(args.iterations * 0.7),
                               refine_every=100, reset_every=3000 if args.iterations > 4000 else 0,
                               max_gaussians=args.max_gaussians, scene_scale=extent)
    trainer = Trainer(params, train.cameras, train_images, cfg, strategy, extent=extent)
    t0 = time.perf_counter()
    with tqdm(total=args.iterations, desc="fit", unit="it", dynamic_ncols=True) as bar:
        for _ in range(args.iterations):
            rep = trainer.step()
            if rep.step % 10 == 0:
                bar.set_postfix(loss=f"{rep.loss:.4f}", gaussians=rep.gaussians)
            bar.update(1)
    seconds = time.perf_counter() - t0
    train_psnr = trainer.evaluate(train.cameras, train_images)
    test_psnr = trainer.evaluate(test.cameras, test_images) if test_images else float("nan")
    scene = scene_from_params(params)
    save_scene(scene, args.out)
    summary = {
        "iterations": args.iterations, "seconds": round(seconds, 1), "gaussians": scene.count,
        "train_psnr": round(train_psnr, 3), "heldout_psnr": None if np.isnan(test_psnr) else round(test_psnr, 3),
        "train_views": len(train.cameras), "heldout_views": len(test.cameras) if test else 0,
        "resolution": [train.cameras[0].width, train.cameras[0].height], "init": source,
    }
    atomic_write_text(str(args.out) + ".json", json.dumps(summary, indent=2))
    print(f"train PSNR {train_psnr:.2f} dB")
    print(f"held-out PSNR {test_psnr:.2f} dB")
    print(f"wrote {args.out} ({scene.count} Gaussians, {seconds:.0f} s)")
    return 0
