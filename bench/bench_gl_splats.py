"""GL splat renderer timings on llvmpipe (EGL, offscreen): frame, depth sort and colour upload.

Usage: .venv/bin/python bench/bench_gl_splats.py [N ...]   (default 10000 100000), 800x600, 20 frames each.
Frames are timed with ctx.finish() (measurement only; the app never calls it in its loop).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import moderngl  # noqa: E402
from synthetic import blob_scene, look_at_camera  # noqa: E402

from app.renderer import SplatRenderer  # noqa: E402
from app.studio import scene_arrays  # noqa: E402

WIDTH, HEIGHT, FRAMES = 800, 600, 20


def measure(ctx: moderngl.Context, n: int) -> dict[str, float]:
    """Milliseconds per static frame, per frame with a moving camera (sort included), per colour upload."""
    scene = blob_scene(n, seed=0, spread=0.6, scale=0.6 / n ** (1 / 3))
    renderer = SplatRenderer(ctx)
    renderer.set_scene(scene_arrays(scene))
    fbo = ctx.framebuffer([ctx.texture((WIDTH, HEIGHT), 4)])
    cams = [look_at_camera((3 * np.sin(a), -0.5, -3 * np.cos(a)), (0, 0, 0), WIDTH, HEIGHT)
            for a in np.linspace(0, 1, FRAMES)]
    renderer.render(cams[0], fbo)
    ctx.finish()  # shader JIT
    t0 = time.perf_counter()
    for _ in range(FRAMES):
        renderer.render(cams[0], fbo)
        ctx.finish()
    static = (time.perf_counter() - t0) / FRAMES
    t0 = time.perf_counter()
    for cam in cams:
        renderer.render(cam, fbo)
        ctx.finish()
    moving = (time.perf_counter() - t0) / FRAMES
    colors = np.random.default_rng(0).uniform(0, 1, (n, 3)).astype(np.float32)
    t0 = time.perf_counter()
    for _ in range(FRAMES):
        renderer.update_colors(colors)
    ctx.finish()
    upload = (time.perf_counter() - t0) / FRAMES
    renderer.release()
    return {"static_ms": static * 1e3, "moving_ms": moving * 1e3, "colour_upload_ms": upload * 1e3}


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [10_000, 100_000]
    ctx = moderngl.create_standalone_context(backend="egl", require=330)
    print(f"{ctx.info['GL_RENDERER']}, {WIDTH}x{HEIGHT}")
    print(f"{'N':>8} {'static ms':>10} {'moving ms':>10} {'colours ms':>11}")
    results = []
    for n in sizes:
        r = measure(ctx, n)
        results.append((n, r))
        print(f"{n:>8} {r['static_ms']:>10.1f} {r['moving_ms']:>10.1f} {r['colour_upload_ms']:>11.2f}")
    print("RESULT " + " ".join(f"N={n}:{r['static_ms']:.0f}ms/{r['moving_ms']:.0f}ms" for n, r in results))


if __name__ == "__main__":
    main()
