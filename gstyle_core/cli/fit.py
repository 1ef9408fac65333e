"""``gstyle fit``: 3DGS optimisation from posed images, with a progress bar and train / held-out PSNR."""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..device import DEVICES
from ..errors import GStyleError

if TYPE_CHECKING:
    import torch

    from ..cameras import CameraSet
    from ..fit.trainer import Trainer
    from ..scene import GaussianScene


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
    p.add_argument("--device", choices=DEVICES, default="auto",
                   help="where renders and the loss run: auto (default: CUDA when torch sees an NVIDIA GPU, with "
                        "gsplat's rasterizer, else the CPU), cpu or cuda (mps: the CPU, gsplat has no Metal backend)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, help="output .ply (or .splat, .spz, .compressed.ply, .sog); OUT.json "
                                                "beside it holds the PSNRs, timings and views")
    p.add_argument("--force", action="store_true", help="overwrite an existing output")


def fit_command(args: argparse.Namespace) -> int:
    """Run ``gstyle fit``."""
    import torch

    from ..fit.model import params_from_scene, scene_from_params
    from ..io.saver import format_of
    from ..outputs import SUMMARY, check_writable, companion, refuse_overwrites

    if format_of(args.out) in (None, "sog-folder"):  # found now, not after the training
        raise GStyleError(f"--out must end in .ply, .compressed.ply, .splat, .spz or .sog, got {args.out}")
    out_files = [Path(args.out), companion(args.out, SUMMARY)]
    refuse_overwrites(out_files, args.force)
    for path in out_files:
        check_writable(path)
    torch.manual_seed(args.seed)
    views = _load_views(args)
    init, source = _initial_scene(views, args)
    train, test = views.train, views.test
    print(f"fit: {len(train.cameras)} training views, {len(test.cameras) if test else 0} held out, "
          f"{train.cameras[0].width}x{train.cameras[0].height}, init from {source}")
    params = params_from_scene(init)
    trainer, seconds = _train(params, views, args)
    train_psnr = trainer.evaluate(train.cameras, views.train_images)
    test_psnr = trainer.evaluate(test.cameras, views.test_images) if views.test_images else float("nan")
    scene = scene_from_params(params)
    _write_outputs(args, scene, _summary(args, views, source, scene.count, seconds, train_psnr, test_psnr))
    print(f"train PSNR {train_psnr:.2f} dB")
    print(f"held-out PSNR {test_psnr:.2f} dB")
    print(f"wrote {args.out} ({scene.count} Gaussians, {seconds:.0f} s)")
    return 0


@dataclass
class _Views:
    """The cameras split into training and held-out views, with their photos."""

    cams: CameraSet  # all views
    train: CameraSet
    test: CameraSet | None  # None: nothing held out
    train_images: list[np.ndarray]
    test_images: list[np.ndarray]


def _load_views(args: argparse.Namespace) -> _Views:
    """Cameras with photos, scaled to ``--width``, every ``--holdout``-th view held out; their images loaded."""
    from ..cameras import load_cameras

    cams = load_cameras(args.cameras or args.scene_dir, image_dir=args.images)
    if not cams.has_images:
        raise GStyleError(f"no images found for the cameras in {args.scene_dir}; fitting needs photos")
    if args.width:
        cams = cams.scaled_to_width(args.width)
    train, test = cams.split_train_test(args.holdout) if args.holdout else (cams, None)
    train_images = train.load_images()
    test_images = test.load_images() if test is not None and test.cameras else []
    return _Views(cams, train, test, train_images, test_images)


def _initial_scene(views: _Views, args: argparse.Namespace) -> tuple[GaussianScene, str]:
    """The starting Gaussians: the sparse points of the cameras, else random points in the training views; and
    a description of which."""
    from ..fit.init import random_points_in_view, scene_from_points

    cams = views.cams
    if cams.points is not None and len(cams.points) > 0:
        return scene_from_points(cams.points, cams.point_colors, args.sh_degree), f"{len(cams.points)} sparse points"
    near = cams.near or 0.1
    far = cams.far or 10.0
    pts = random_points_in_view(views.train.cameras, 50_000, near, far, args.seed)
    return scene_from_points(pts, None, args.sh_degree), "50000 random points (no sparse points found)"


def fit_device(args: argparse.Namespace) -> str:
    """The device renders run on for ``--device`` (MPS renders on the CPU: gsplat has no Metal backend); the choice
    and its reason are printed and kept for OUT.json."""
    from ..device import describe, resolve_device

    choice = resolve_device(getattr(args, "device", "auto"))
    args.device_choice, args.device_note = choice, describe(choice)
    print(f"device: {args.device_note}")
    return str(choice.raster_device)


def _train(params: torch.nn.ParameterDict, views: _Views, args: argparse.Namespace) -> tuple[Trainer, float]:
    """``--iterations`` steps of 3DGS training with densification, behind a progress bar: (trainer, seconds)."""
    import torch
    from tqdm import tqdm

    from ..device import out_of_memory
    from ..fit.strategy import DefaultStrategy
    from ..fit.trainer import FitConfig, Trainer, scene_scale

    cfg = FitConfig(iterations=args.iterations, sh_degree=args.sh_degree, backend=args.backend, seed=args.seed,
                    sh_increase_every=max(1, args.iterations // 4), device=fit_device(args))
    extent = scene_scale(views.train.cameras)
    strategy = DefaultStrategy(refine_start=min(500, args.iterations // 10), refine_stop=int(args.iterations * 0.7),
                               refine_every=100, reset_every=3000 if args.iterations > 4000 else 0,
                               max_gaussians=args.max_gaussians, scene_scale=extent)
    trainer = Trainer(params, views.train.cameras, views.train_images, cfg, strategy, extent=extent)
    t0 = time.perf_counter()
    with tqdm(total=args.iterations, desc="fit", unit="it", dynamic_ncols=True) as bar:
        for i in range(args.iterations):
            try:
                rep = trainer.step()
            except torch.OutOfMemoryError as error:  # a GPU's: one line that says what to lower
                raise out_of_memory(args.device_choice, f"fit iteration {i + 1} with {len(trainer.params['means']):,} "
                                    "Gaussians", lighter="set a lower --max-gaussians") from error
            if rep.step % 10 == 0:
                bar.set_postfix(loss=f"{rep.loss:.4f}", gaussians=rep.gaussians)
            bar.update(1)
    return trainer, time.perf_counter() - t0


def _summary(args: argparse.Namespace, views: _Views, source: str, count: int, seconds: float,
             train_psnr: float, test_psnr: float) -> dict:
    """``OUT.json``'s summary: iterations, time, Gaussians, PSNRs, views, resolution and initialisation."""
    train, test = views.train, views.test
    return {
        "iterations": args.iterations, "seconds": round(seconds, 1), "gaussians": count,
        "train_psnr": round(train_psnr, 3), "heldout_psnr": None if np.isnan(test_psnr) else round(test_psnr, 3),
        "train_views": len(train.cameras), "heldout_views": len(test.cameras) if test else 0,
        "resolution": [train.cameras[0].width, train.cameras[0].height], "init": source,
        "decisions": {"device": getattr(args, "device_note", "cpu")},
    }


def _write_outputs(args: argparse.Namespace, scene, summary: dict) -> None:
    """OUT.ply and OUT.json (``outputs.companion``), appearing together or not at all."""
    from ..atomic import atomic_write_text
    from ..io import save_scene
    from ..io.saver import format_of
    from ..outputs import SUMMARY, OutputGroup, companion

    with OutputGroup() as group:
        group.write(companion(args.out, SUMMARY), lambda tmp: atomic_write_text(tmp, json.dumps(summary, indent=2)))
        group.write(args.out, lambda tmp: save_scene(scene, tmp, fmt=format_of(args.out)))
