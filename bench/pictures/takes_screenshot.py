"""Screenshot of the studio comparing a take with the current run (docs/notes/artist-controls.md).

    .venv/bin/python bench/pictures/takes_screenshot.py [--first 0.2] [--second 0.8] [--out docs/studio_takes.png]

Opens the studio headless (EGL) on the demo with two paintings mixed (The Starry Night and The Great Wave from
``../shared/data/styles``), runs the real engine to the end at style mix ``--first``, exports it (it becomes a
take), restarts at ``--second``, runs to the end again and shows the compare view: the current run left, the take
right. Prints the wall time of each run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from app.engine_factory import make_stylizer  # noqa: E402
from app.open_files import load_scene_with_cameras  # noqa: E402
from app.panels import Command  # noqa: E402
from app.studio import StudioApp  # noqa: E402
from app.window import open_window  # noqa: E402

STYLES = ROOT.parent / "shared" / "data" / "styles"


def run_frames(window, app, until, timeout: float, fps: float = 30.0) -> float:
    """Draw frames until ``until()`` (or ``timeout`` s); the seconds it took."""
    t0 = time.perf_counter()
    while not until() and time.perf_counter() - t0 < timeout:
        start = time.perf_counter()
        window.draw(app.frame)
        if app.engine.bridge is not None and app.engine.bridge.state.error:
            raise SystemExit(f"worker failed: {app.engine.bridge.state.error}")
        time.sleep(max(0.0, 1.0 / fps - (time.perf_counter() - start)))
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--first", type=float, default=0.2, help="style mix of the exported take")
    p.add_argument("--second", type=float, default=0.8, help="style mix of the current run")
    p.add_argument("--out", default=str(ROOT / "docs" / "studio_takes.png"))
    p.add_argument("--size", default="1280x820")
    args = p.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    out_dir = ROOT / "out" / "takes_screenshot"
    window = open_window(width, height, headless=True)
    first, second = STYLES / "starry_night_vangogh.jpg", STYLES / "great_wave_hokusai.jpg"
    app = StudioApp(window.ctx, loaded=load_scene_with_cameras(None, None), style_path=str(first),
                    engine_factory=make_stylizer, engine_config={}, output_dir=str(out_dir))
    try:
        app.paintings.set_style(str(second), slot=1, mix=args.first)
        app.engine.start()
        done = lambda: app.engine.bridge.state.done  # noqa: E731
        print(f"run at mix {args.first}: {run_frames(window, app, done, 900):.0f} s")
        before = len(app.engine.bridge.state.exported)
        app.outputs.export()
        bridge = app.engine.bridge
        run_frames(window, app, lambda: len(bridge.state.exported) > before and bool(app.takes.shelf.takes), 60)
        app.execute(Command("set_params", {"style_mix": args.second}))
        app.engine.start()
        run_frames(window, app, lambda: not app.engine.bridge.state.done, 30)
        print(f"run at mix {args.second}: {run_frames(window, app, done, 900):.0f} s")
        app.execute(Command("show_take", {"index": 0, "compare": True}))
        app.status.say(f"comparing with {app.takes.shelf.takes[0].name} (style mix {args.first})")
        run_frames(window, app, lambda: False, 6)
        app.progressive = False
        screen = window.draw(app.frame)
        print(f"wrote {app.outputs.save_png(args.out, app.outputs.capture(screen))}")
    finally:
        app.close()
        window.close()


if __name__ == "__main__":
    main()
