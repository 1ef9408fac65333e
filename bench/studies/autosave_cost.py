"""What the studio's own saves cost (issue #65: a crash loses at most about a minute of steps, saving takes at most 3 %
of the step time): for each scene, an engine built as the studio's worker builds it, stepped, then its session
checkpoint written as the worker writes it (``RunSaves.save_state``'s ``save_checkpoint``); prints the step time, the
save's time and size, the interval ``SavePacing`` chooses after that save and the share of the stepping time the saves
then take.

    .venv/bin/python bench/studies/autosave_cost.py --scenes demo /tmp/cap1200000.ply --steps 20
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from gstyle_core.assets import DEFAULT_STYLE, DEMO_SCENE  # noqa: E402
from gstyle_core.engine.build import BuildRequest, build_stylizer  # noqa: E402
from gstyle_core.engine.checkpoint import save_checkpoint  # noqa: E402
from gstyle_core.engine.save_pacing import SavePacing  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402


def measure(scene: str, steps: int, width: int | None) -> dict:
    """Build, step ``steps`` times after the ground truth and pre-process, save twice; the figures of the second
    save (the first warms the file system)."""
    built = build_stylizer(BuildRequest(scene=scene, style=str(DEFAULT_STYLE), preset="preview",
                                        overrides={"working_width": width} if width else {}))
    engine = built.engine
    while engine.phase not in ("stylize", "done"):
        engine.step()
    t0 = time.perf_counter()
    for _ in range(steps):
        engine.step()
    step_s = (time.perf_counter() - t0) / steps
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "session.ckpt"
        for _ in range(2):
            t0 = time.perf_counter()
            save_checkpoint(path, engine.state_dict(), {"kind": "studio"})
            save_s = time.perf_counter() - t0
        size = path.stat().st_size
    pacing = SavePacing(clock=lambda: 0.0)  # the worker's own pacing after this save: the next one's time from now
    pacing.saved(save_s)
    interval = pacing.next_at
    whole = getattr(engine, "full_input", None) or engine.input_scene  # a capture on its level of detail: all of it
    return {"scene": Path(scene).name, "gaussians": whole.count, "held": engine.input_scene.count, "step_s": step_s,
            "save_s": save_s, "mib": size / 2**20, "interval_s": interval, "share": save_s / (interval + save_s),
            "steps_lost_at_most": (interval + save_s) / step_s}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["demo"], help="scene files ('demo': the bundled one)")
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--width", type=int, default=None, help="the run's working width (default: the preset's)")
    args = parser.parse_args()
    print(f"cpu: {cpu_description()}")
    print(f"{'scene':<22}{'Gaussians':>11}{'held':>9}{'step s':>8}{'save s':>8}{'MiB':>7}{'every s':>9}{'share':>7}"
          f"{'steps lost':>11}")
    for scene in args.scenes:
        row = measure(str(DEMO_SCENE) if scene == "demo" else scene, args.steps, args.width)
        print(f"{row['scene']:<22}{row['gaussians']:>11,}{row['held']:>9,}{row['step_s']:>8.3f}{row['save_s']:>8.3f}{row['mib']:>7.1f}"
              f"{row['interval_s']:>9.1f}{row['share']:>7.1%}{row['steps_lost_at_most']:>11.0f}")


if __name__ == "__main__":
    main()
