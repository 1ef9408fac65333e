"""What ``gstyle-studio`` does without a display: stylize the scene headless (the same engine and preset as the
studio) and write before/after renders large enough to judge the strokes."""

from __future__ import annotations

import argparse
from pathlib import Path


def stylize_without_display(args: argparse.Namespace, width: int = 640) -> tuple[Path, Path]:
    """Run ``gstyle stylize`` on the studio's scene and style into ``args.output_dir`` and write
    ``<stem>_before_after.png``: two evaluation views, input above stylized, ``width`` px each. Returns the
    stylized scene's path and the picture's."""
    from gstyle_core.cli.stylize import add_stylize_arguments, stylize_command
    from gstyle_core.io import load_scene
    from gstyle_core.scene_images import before_after_picture, load_scene_and_cameras, save_png

    out_dir = Path(args.output_dir or "out")
    stem = Path(args.scene).stem if args.scene else "demo"
    out = out_dir / f"{stem}_stylized.ply"
    parser = argparse.ArgumentParser()
    add_stylize_arguments(parser)
    argv = ["--preset", args.preset, "--out", str(out), "--force"]
    for flag, value in (("--defaults", getattr(args, "defaults", None)), ("--cameras", args.cameras),
                        ("--vgg-weights", args.vgg_weights), ("--clip-weights", args.clip_weights),
                        ("--precision", getattr(args, "precision", None)),
                        ("--device", getattr(args, "device", None))):
        if value:
            argv += [flag, str(value)]
    styles = [args.style] if isinstance(args.style, str) else list(args.style or [])
    for style in styles:
        argv += ["--style", str(style)]
    if len(styles) == 2:
        mix = 0.5 if getattr(args, "style_mix", None) is None else float(args.style_mix)
        argv += ["--style-weights", f"{1.0 - mix:g},{mix:g}"]
    if args.scene:
        argv.insert(0, str(args.scene))
    stylize_command(parser.parse_args(argv))
    scene, _report, cams = load_scene_and_cameras(args.scene, args.cameras)
    stylized, _ = load_scene(out)
    picture = out_dir / f"{stem}_before_after.png"
    save_png(picture, before_after_picture(scene, stylized, cams.cameras, n_views=2, width=width))
    return out, picture
