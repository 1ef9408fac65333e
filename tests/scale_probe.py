"""A short stylization of a capture densified from the demo, in its own process (``tests/test_capture_scale.py``,
``engine/resources.py``'s model):

    python tests/scale_probe.py N [WIDTH]

builds the engine as ``gstyle stylize`` does (generated orbit, the ``preview`` preset, the real VGG objective) on
``densify(demo, N)`` with short budgets (one epoch, 4-iteration refits, a colour-gradient split; at ``WIDTH`` px,
default the preset's), steps it to the end and prints one JSON line: the process's peak resident memory
(``VmHWM``), the most Gaussians it held and the count of the result."""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench")]

from densify import densify  # noqa: E402

from gstyle_core.assets import DEMO_SCENE  # noqa: E402
from gstyle_core.engine.build import BuildRequest, build_stylizer  # noqa: E402
from gstyle_core.io import load_scene, save_scene  # noqa: E402
from gstyle_core.machine import peak_rss_bytes  # noqa: E402

SHORT = {"epochs": 1.0, "refit_iterations": 4, "lod": "off"}  # the cap's model is of Gaussians held as they are


def main(n: int, width: int | None = None) -> dict:
    demo, _ = load_scene(DEMO_SCENE)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "capture.ply"
        save_scene(densify(demo, n), path)
        overrides = {**SHORT, **({"working_width": width} if width else {})}
        engine = build_stylizer(BuildRequest(scene=str(path), preset="preview", overrides=overrides)).engine
        most = engine.gaussian_count
        while not engine.done:
            engine.step()
            most = max(most, engine.gaussian_count)
        out = engine.stylized_scene()
    return {"n": n, "peak": peak_rss_bytes(), "most": most, "out": out.count, "capacity": engine.decisions["capacity"]}


if __name__ == "__main__":
    print("PROBE " + json.dumps(main(int(sys.argv[1]), int(sys.argv[2]) if len(sys.argv) > 2 else None)))
