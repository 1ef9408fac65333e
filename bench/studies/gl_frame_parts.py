"""Where a moving splat frame's time goes on llvmpipe: depth sort of all Gaussians (``app/depth_sort.py``'s kernel,
which runs on the renderer's sorter thread, not in the frame), projection pass, draw, and the draw with a 1×1
scissor (no fill), at full and reduced detail (fraction of the Gaussians drawn, most important first).

    .venv/bin/python bench/studies/gl_frame_parts.py [--scene PATH] [--size 200x150] [--frames 16]

The camera orbits the scene's centre; every part is timed with ``ctx.finish()``. Prints a table of milliseconds
per frame and the quad pixels the projection pass produced (fill work).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import moderngl  # noqa: E402
from synthetic import look_at_camera  # noqa: E402

from app.depth_sort import depth_order  # noqa: E402
from app.main import parse_size  # noqa: E402
from app.renderer import SplatRenderer  # noqa: E402
from app.studio import scene_arrays  # noqa: E402
from gstyle_core.assets import DEMO_SCENE  # noqa: E402
from gstyle_core.io import load_scene  # noqa: E402


def quad_pixels(renderer: SplatRenderer) -> float:
    """Total area (pixels) of the quads of the last projection pass."""
    axes = renderer.projected()["axes"]
    return float((4 * np.abs(axes[:, 0] * axes[:, 3] - axes[:, 1] * axes[:, 2])).sum())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default=str(DEMO_SCENE))
    p.add_argument("--size", type=parse_size, default=(200, 150))
    p.add_argument("--frames", type=int, default=16)
    args = p.parse_args()
    scene = load_scene(args.scene)[0]
    ctx = moderngl.create_standalone_context(backend="egl", require=330)
    renderer = SplatRenderer(ctx)
    renderer.set_scene(scene_arrays(scene))
    width, height = args.size
    fbo = ctx.framebuffer([ctx.texture((width, height), 4)])
    centre = scene.means.mean(0)
    radius = float(np.median(np.linalg.norm(scene.means - centre, axis=1))) * 2.5
    cams = [look_at_camera(centre + radius * np.array([np.sin(a), -0.3, -np.cos(a)]), centre, width, height)
            for a in np.linspace(0, 1, args.frames)]
    renderer.render(cams[0], fbo)
    ctx.finish()  # shader compilation
    print(f"{scene.count} Gaussians, {width}x{height}, {ctx.info['GL_RENDERER']}")
    print(f"{'detail':>6} {'full sort':>9} {'project ms':>10} {'draw ms':>8} {'no-fill ms':>10} {'quad Mpx':>9}")
    for detail in (1.0, 0.5, 0.25, 0.12):
        t = {"sort": 0.0, "project": 0.0, "draw": 0.0, "nofill": 0.0}
        pixels = 0.0
        for cam in cams:
            t0 = time.perf_counter()
            depth_order(renderer._means, np.asarray(cam.world_to_cam), 0.01)
            t["sort"] += time.perf_counter() - t0
            renderer.prepare(cam, detail)
            t0 = time.perf_counter()
            renderer._project(cam)
            ctx.finish()
            t["project"] += time.perf_counter() - t0
            pixels += quad_pixels(renderer)
            t0 = time.perf_counter()
            renderer.render(cam, fbo, detail=detail)
            ctx.finish()
            t["draw"] += time.perf_counter() - t0
            t0 = time.perf_counter()
            renderer.render(cam, fbo, detail=detail, scissor=(0, 0, 1, 1))
            ctx.finish()
            t["nofill"] += time.perf_counter() - t0
        ms = {k: 1e3 * v / len(cams) for k, v in t.items()}
        print(f"{detail:>6.2f} {ms['sort']:>9.1f} {ms['project']:>10.1f} {ms['draw']:>8.1f} {ms['nofill']:>10.1f} "
              f"{pixels / len(cams) / 1e6:>9.2f}")


if __name__ == "__main__":
    main()
