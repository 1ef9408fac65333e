"""What ``gstyle-studio`` does without a display: stylize the scene headless (the same engine and preset as the
studio) and write before/after renders large enough to judge the strokes."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def stylize_without_display(args: argparse.Namespace, width: int = 640) -> Path:
    """Run ``gstyle stylize`` on the studio's scene and style into ``args.output_dir`` and write
    ``<stem>_before_after.png``: two evaluation views, input above stylized, ``width`` px each. Returns its path."""
    from gstyle_core.io import load_scene
    from gstyle_core.pipeline.cli import add_stylize_arguments, stylize_command
    from gstyle_core.pipeline.stylizer import choose_views
    from gstyle_core.render_cli import load_scene_and_cameras, render_scene_image, save_png

    out_dir = Path(args.output_dir)
    stem = Path(args.scene).stem if args.scene else "demo"
    out = out_dir / f"{stem}_stylized.ply"
    parser = argparse.ArgumentParser()
    add_stylize_arguments(parser)
    argv = ["--preset", args.preset, "--out", str(out), "--force"]
    for flag, value in (("--style", args.style), ("--cameras", args.cameras), ("--vgg-weights", args.vgg_weights),
                        ("--clip-weights", args.clip_weights)):
        if value:
            argv += [flag, str(value)]
    if args.scene:
        argv.insert(0, str(args.scene))
    stylize_command(parser.parse_args(argv))
    scene, _report, cams = load_scene_and_cameras(args.scene, args.cameras)
    stylized, _ = load_scene(out)
    views = [cams.cameras[i].resized_to_width(width) for i in choose_views(cams.cameras, 2)]
    before = np.concatenate([render_scene_image(scene, c) for c in views], axis=1)
    after = np.concatenate([render_scene_image(stylized, c) for c in views], axis=1)
    picture = out_dir / f"{stem}_before_after.png"
    save_png(picture, np.concatenate([before, after], axis=0))
    return picture
