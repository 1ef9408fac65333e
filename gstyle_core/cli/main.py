"""The ``gstyle`` command line: info, convert, render, fit, stylize, batch, cache.

Every error a user can cause (bad file, missing cameras, missing weights, an output that cannot be written: a full
disk, a read-only or forbidden folder) is a ``GStyleError`` and is printed as one line without a traceback; the exit
status is then 2. Any other error is a bug: one line too (what failed, where: for ``stylize`` the phase, the step,
the controls in force and the ``--resume`` command that goes on from the last finished step) naming the crash log
that holds its traceback (``crash.py``); the exit status is then 1.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from .commands import run_parsed


def _cmd_info(args: argparse.Namespace) -> int:
    from ..io import load_scene

    scene, report = load_scene(args.scene)
    print(report.summary())
    lo, hi = scene.bounds()
    print(f"bounding box: min {lo.round(3).tolist()} max {hi.round(3).tolist()}")
    return 0


def _cmd_convert(args: argparse.Namespace) -> int:
    from ..atomic import refuse_overwrite
    from ..io import load_scene, save_scene
    from ..outputs import check_writable

    refuse_overwrite(args.output, args.force, inputs=[args.input])
    check_writable(args.output)
    scene, report = load_scene(args.input)
    if args.sh0:
        scene = scene.with_sh_degree(0)
    save_scene(scene, args.output)
    print(f"wrote {args.output}: {scene.count} Gaussians, SH degree {scene.sh_degree} ({report.format})")
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from .render import render_command

    return render_command(args)


def _cmd_fit(args: argparse.Namespace) -> int:
    from .fit import fit_command

    return fit_command(args)


def _cmd_cache(args: argparse.Namespace) -> int:
    from .cache import cache_command

    return cache_command(args)


def _cmd_stylize(args: argparse.Namespace) -> int:
    from .stylize import stylize_command

    return stylize_command(args)


def _cmd_batch(args: argparse.Namespace) -> int:
    from .batch import batch_command

    return batch_command(args)


def installed_version() -> str:
    """The installed distribution's version (``gstyle-studio`` in its metadata), or "unknown" when it is not
    installed (run from a bare checkout)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("gstyle-studio")
    except PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``gstyle``."""
    p = argparse.ArgumentParser(prog="gstyle", description="G-Style Studio command line tools.")
    p.add_argument("--version", action="version", version=f"%(prog)s {installed_version()}")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("info", help="count, SH degree, bounding box and validation report of a scene")
    s.add_argument("scene")
    s.set_defaults(func=_cmd_info)

    s = sub.add_parser("convert", help="convert between .ply / .splat / .spz / compressed .ply / SOG (writes all of "
                                       "them; name.compressed.ply is PlayCanvas's compressed PLY, name.sog or "
                                       "DIR/meta.json PlayCanvas SOG)")
    s.add_argument("input", help="scene file, or a SOG folder")
    s.add_argument("output", help="output file: .ply, .splat, .spz (Niantic, v3), .compressed.ply (PlayCanvas), .sog "
                                  "(PlayCanvas SOG v2) or DIR/meta.json (SOG with its images in DIR)")
    s.add_argument("--sh0", action="store_true", help="drop view-dependent SH (keep the diffuse colour)")
    s.add_argument("--force", action="store_true", help="overwrite an existing output")
    s.set_defaults(func=_cmd_convert)

    s = sub.add_parser("render", help="render a scene from a camera to a PNG, or a turntable / camera-path video")
    s.add_argument("scene", nargs="?", default=None, help="scene file (default: the bundled demo)")
    s.add_argument("--cameras", help="cameras.json, COLMAP folder, LLFF folder or .npz (default: generated orbit); "
                                     "with a video --out and no --turntable / --camera-path the video follows them")
    s.add_argument("--camera", type=int, default=None, help="index of the camera to render (default 0)")
    s.add_argument("--width", type=int, default=None, help="output width in pixels (height keeps the aspect)")
    s.add_argument("--backend", choices=["fast", "reference"], default="fast")
    s.add_argument("--turntable", type=int, default=None, metavar="N",
                   help="a video of N frames orbiting the scene (640x480, or the size of --cameras' first camera)")
    s.add_argument("--camera-path", default=None, metavar="JSON",
                   help="a video along a nerfstudio camera_path.json (its size, field of view and fps)")
    s.add_argument("--fps", type=float, default=None, help="video frame rate (default 30, or the camera path's)")
    s.add_argument("--out", default=None,
                   help="PNG to write (default out/render.png); for a video FILE.mp4, FILE.gif or a folder DIR/ of "
                        "numbered PNGs (default out/turntable.mp4)")
    s.add_argument("--force", action="store_true", help="overwrite an existing output")
    s.set_defaults(func=_cmd_render)

    from .fit import add_fit_arguments

    s = sub.add_parser("fit", help="fit a 3DGS scene to posed images (3DGS optimisation)")
    add_fit_arguments(s)
    s.set_defaults(func=_cmd_fit)

    _add_engine_commands(sub)

    from .cache import add_cache_arguments

    s = sub.add_parser("cache", help="list the cache folder (converted weights, checkpoints) or --clear it")
    add_cache_arguments(s)
    s.set_defaults(func=_cmd_cache)
    return p


def _add_engine_commands(sub) -> None:
    """``gstyle stylize`` and ``gstyle batch`` on the subcommand parsers ``sub``."""
    try:
        from .stylize import add_stylize_arguments
    except ImportError:  # the stylization engine is optional until it lands
        add_stylize_arguments = None
    if add_stylize_arguments is not None:
        s = sub.add_parser("stylize", help="stylize a scene after a painting (G-Style)")
        add_stylize_arguments(s)
        s.set_defaults(func=_cmd_stylize)
        from .batch import add_batch_arguments

        s = sub.add_parser("batch", conflict_handler="resolve", allow_abbrev=False,
                           help="stylize every scene after every painting (gstyle stylize's options for each job)")
        add_batch_arguments(s)
        s.set_defaults(func=_cmd_batch)


def run(argv: Sequence[str] | None, func_wrapper: Callable[[Callable[[], int]], int] | None = None) -> int:
    """Parse ``argv`` and run the command; GStyleError and bad paths become one line and exit status 2 (writes
    that fail are ``OutputWriteError``s: ``cannot write PATH: CAUSE``), any other error one line naming its crash
    log and exit status 1."""
    args = build_parser().parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # as given: ``gstyle stylize``'s resume command
    return run_parsed(args)


def main() -> None:
    """Console-script entry point."""
    sys.exit(run(sys.argv[1:]))


if __name__ == "__main__":
    main()
