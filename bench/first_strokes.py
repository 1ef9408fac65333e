"""How soon the studio shows the painting's strokes: the real app headless, its worker stylizing, screenshots on a
clock.

Opens the studio headless (glfw NULL platform + EGL) on a scene with the real engine in its spawned worker, at the
studio's frame cap, camera still, panel hidden, and saves a screenshot at each of ``--at`` seconds after the engine
was started (the user's wait), with the worker's phase and stylization step then.

    .venv/bin/python bench/first_strokes.py [--scene PATH] [--style IMAGE] [--at 30,60,90] [--out out/first_strokes]

Prints a table and ``RESULT stylize_started_s=… steps_at_<t>s=…``. Look at the PNGs: that is the measurement.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.engine_factory import make_stylizer  # noqa: E402
from app.main import parse_size  # noqa: E402
from app.open_files import load_scene_with_cameras  # noqa: E402
from app.studio import StudioApp  # noqa: E402
from app.window import open_window  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default=None, help="scene (default: the bundled demo)")
    p.add_argument("--style", default=str(ROOT / "assets" / "styles" / "starry_night.jpg"))
    p.add_argument("--at", default="30,60,90", help="seconds after the engine starts at which to screenshot")
    p.add_argument("--size", type=parse_size, default=(800, 600))
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--out", default=str(ROOT / "out" / "first_strokes"), help="folder for the screenshots")
    args = p.parse_args()
    marks = sorted(float(t) for t in args.at.split(","))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    window = open_window(*args.size, headless=True)
    loaded = load_scene_with_cameras(args.scene, None)
    app = StudioApp(window.ctx, loaded=loaded, style_path=args.style, engine_factory=make_stylizer,
                    engine_config={"style": args.style}, output_dir=str(out), show_ui=False)
    rows, stylize_started = [], None
    try:
        t0 = time.perf_counter()
        app.engine.start()
        while marks:
            start = time.perf_counter()
            screen = window.draw(app.frame)
            report = (app.engine.bridge.state.last_report or {}) if app.engine.bridge is not None else {}
            if app.engine.bridge is not None and app.engine.bridge.state.error:
                raise SystemExit(f"worker failed: {app.engine.bridge.state.error}")
            elapsed = time.perf_counter() - t0
            if stylize_started is None and report.get("phase") == "stylize":
                stylize_started = elapsed
            if elapsed >= marks[0]:
                t = marks.pop(0)
                path = out / f"at_{int(t):03d}s.png"
                app.outputs.save_png(str(path), app.outputs.capture(screen))
                rows.append((t, report.get("phase", "-"), f"{report.get('step', 0)}/{report.get('total_steps', 0)}",
                             path))
            time.sleep(max(0.0, 1.0 / args.fps - (time.perf_counter() - start)))
    finally:
        app.close()
        window.close()
    print(f"{'t (s)':>6}  {'phase':<12} {'step':>9}  screenshot")
    for t, phase, step, path in rows:
        print(f"{t:6.0f}  {phase:<12} {step:>9}  {path}")
    started = "never" if stylize_started is None else f"{stylize_started:.1f}"
    steps = " ".join(f"steps_at_{int(t)}s={step}" for t, _, step, _ in rows)
    print(f"RESULT stylize_started_s={started} {steps}")


if __name__ == "__main__":
    main()
