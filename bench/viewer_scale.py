"""The viewer at 0.2-6 M Gaussians: the depth sort off the frame, frame rates, load time and host memory.

Scenes are built by densifying a real capture (``biker.spz``, 152,746 Gaussians): each Gaussian is copied
k = ceil(n / 152,746) times (the first n copies kept), every copy moved by a jitter drawn within the Gaussian's own
ellipsoid (a normal of 0.5 sigma along each of its axes) and its scales shrunk by k^(-1/3), so the copies fill the
original's volume as a denser capture would. Per size:

* sort: the old order (numpy argsort of float64 depths, as ``splat_data.back_to_front_order``) against the new
  one (``app/depth_sort.py``: a numba counting sort of 16-bit keys, and of ``key_bits(n)`` keys) and numpy's
  stable argsort of the same integer keys; the median over the orbit's views, all timed in this one run;
* quality: the largest depth gap of an out-of-order pair in bucket widths (1 at most by construction), and one
  full frame drawn with the quantised order against the exact order (mean and 99.9th percentile of the 8-bit
  difference);
* frames: headless EGL at ``--size`` through the studio's ``SceneView`` (progressive pacing, its 20 ms budget) and
  the studio's frame cap; the camera orbits (4 px of drag a frame, as ``bench/ui.py``) for ``--seconds`` after
  one second to let the governor settle, then stays still for ``--seconds``. Frame time = interval between frame
  starts, each frame ending with ``ctx.finish()``. ``drawn_share_orbiting``: median fraction of the Gaussians the
  moving frames drew; ``frame_blocked_by_sort_ms``: the longest a moving frame waited for a sort; then, once
  the still view's image is built, the median work of a frame (draw and ``ctx.finish()``) and the sorts it asked;
* load: the scene written to a temporary .ply, the time of ``gstyle_core.io.load_scene`` reading it back;
* host memory: the process's resident memory after the viewer opened the scene and drew (orbit and still) minus
  before, per Gaussian (on llvmpipe this includes the GL textures and buffers, which live in host memory), and
  the bytes per Gaussian of the arrays the renderer and its sorter keep.

    .venv/bin/python bench/viewer_scale.py [--sizes 1200000,6000000] [--seconds 4] [--size 800x600] [--fps 60]

Ends with one line per size: ``RESULT n=… sort_ms=… frame_blocked_by_sort_ms=… drawn_share_orbiting=… load_s=…
host_bytes_per_gaussian=…`` (sort_ms: the new sort of all n, ``DEFAULT_BITS`` keys, off the UI thread).
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import moderngl  # noqa: E402

from app.camera_control import CameraControl  # noqa: E402
from app.depth_sort import DEFAULT_BITS, DepthSorter, SortScratch, depth_order, key_bits  # noqa: E402
from app.main import parse_size  # noqa: E402
from app.renderer import NEAR, SplatRenderer, read_rgb  # noqa: E402
from app.scene_view import SceneView, ViewPass  # noqa: E402
from app.splat_data import back_to_front_order, rotation_matrices, scene_arrays  # noqa: E402
from gstyle_core.cameras.camera import Camera  # noqa: E402
from gstyle_core.cameras.framing import scene_box  # noqa: E402
from gstyle_core.cameras.generate import finite_points, robust_centre_radius  # noqa: E402
from gstyle_core.io import load_scene, save_scene  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402
from gstyle_core.scene import GaussianScene  # noqa: E402

SOURCE = ROOT.parent / "shared" / "data" / "scenes" / "playcanvas" / "biker.spz"
BACKGROUND = (0.1, 0.1, 0.12)


def densify(scene: GaussianScene, n: int, seed: int = 0) -> GaussianScene:
    """``n`` Gaussians: copies of ``scene``'s, each moved within its own ellipsoid, scales shrunk by k^(-1/3)."""
    k = math.ceil(n / scene.count)
    index = np.tile(np.arange(scene.count), k)[:n]
    rng = np.random.default_rng(seed)
    means = np.empty((n, 3), np.float32)
    chunk = 1 << 20
    for start in range(0, n, chunk):  # in chunks: [chunk, 3, 3] float64 rotations at a time
        part = index[start:start + chunk]
        scales = np.exp(scene.log_scales[part].astype(np.float64))
        jitter = rng.normal(0, 0.5, (part.size, 3)) * scales  # along the Gaussian's own axes
        offset = np.einsum("nij,nj->ni", rotation_matrices(scene.quats[part]), jitter)
        means[start:start + chunk] = scene.means[part] + offset
    shrink = np.float32(math.log(k) / 3)
    return GaussianScene(means, scene.log_scales[index] - shrink, scene.quats[index].copy(),
                         scene.opacity_logits[index].copy(), scene.sh_dc[index].copy(),
                         np.zeros((n, 0, 3), np.float32))


def rss_bytes() -> int:
    """Resident memory of this process (Linux /proc) once freed heap memory went back to the system (glibc's
    malloc_trim: what is live, not what the allocator kept)."""
    import ctypes

    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def median_ms(fn: Callable[[np.ndarray], object], views: list[Camera]) -> float:
    """Median wall time (ms) of ``fn(world_to_cam)`` over ``views``, once each."""
    times = []
    for cam in views:
        t0 = time.perf_counter()
        fn(cam.world_to_cam)
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times))


def numpy_key_order(means: np.ndarray, view: np.ndarray, bits: int) -> np.ndarray:
    """The same quantised keys as ``depth_order``, sorted by numpy's stable argsort (radix for 16-bit keys)."""
    z = means @ np.asarray(view[2, :3], np.float32) + np.float32(view[2, 3])
    visible = np.flatnonzero(np.isfinite(z) & (z > NEAR))
    zv = z[visible].astype(np.float64)
    lo, hi = zv.min(), zv.max()
    keys = ((hi - zv) * (((1 << bits) - 1) / max(hi - lo, 1e-30))).astype(np.uint16 if bits <= 16 else np.uint32)
    return visible[np.argsort(keys, kind="stable")].astype(np.int32)


def orbit_control(scene: GaussianScene, width: int, height: int) -> CameraControl:
    """The studio's framing of a bare scene file: the whole (robust) box in view from the side."""
    control = CameraControl()
    centre, radius = robust_centre_radius(finite_points(scene.means))
    control.frame(centre, radius)
    control.frame_box(*scene_box(scene.means), width, height)
    return control


def orbit_views(control: CameraControl, width: int, height: int, count: int) -> list[Camera]:
    """``count`` cameras around the orbit (the control is left where it started)."""
    start = control.pose.copy()
    cams = []
    for _ in range(count):
        control.orbit(1256.0 / count, 0.0)  # a full turn in ``count`` steps at 0.005 rad a pixel
        cams.append(control.camera(width, height))
    control.pose = start
    return cams


def sort_times(means: np.ndarray, views: list[Camera], subset: np.ndarray | None) -> dict[str, float]:
    """Median ms of each way to order ``means`` over ``views`` (and of the old and new sort of a ``subset``)."""
    n = means.shape[0]
    scratch = SortScratch()
    count_bits = key_bits(n)
    ways: dict[str, Callable[[np.ndarray], object]] = {
        "old argsort": lambda v: back_to_front_order(means, v, NEAR),
        f"numba {DEFAULT_BITS} bits": lambda v: depth_order(means, v, NEAR, DEFAULT_BITS, None, scratch),
        "numba key_bits(n)": lambda v: depth_order(means, v, NEAR, count_bits, None, scratch),
        f"numpy {DEFAULT_BITS} bits": lambda v: numpy_key_order(means, v, DEFAULT_BITS),
        "numpy key_bits(n)": lambda v: numpy_key_order(means, v, count_bits),
    }
    if subset is not None:
        sub = means[subset]
        ways["old argsort, moving subset"] = lambda v: back_to_front_order(sub, v, NEAR)
        ways[f"numba {DEFAULT_BITS} bits, moving subset"] = lambda v: depth_order(means, v, NEAR, DEFAULT_BITS,
                                                                                  subset, scratch)
    return {name: median_ms(way, views) for name, way in ways.items()}


def inversion_buckets(means: np.ndarray, cam: Camera, bits: int) -> float:
    """The largest depth gap of an out-of-order pair in the quantised order, in bucket widths."""
    order = depth_order(means, cam.world_to_cam, NEAR, bits)
    view = np.asarray(cam.world_to_cam, np.float64)
    z = means[order].astype(np.float64) @ view[2, :3] + view[2, 3]
    width = (z.max() - z.min()) / ((1 << bits) - 1)
    return float(np.max(z[1:] - np.minimum.accumulate(z)[:-1], initial=0.0) / width)


def exact_sort(request, scratch) -> np.ndarray:
    """The old exact order (float64 argsort), as a sorter's work."""
    view = np.zeros((4, 4))
    view[2] = request.view_row
    order = back_to_front_order(request.means if request.subset is None else request.means[request.subset],
                                view, request.near)
    return order if request.subset is None else request.subset[order]


def image_difference(ctx: moderngl.Context, arrays: dict, cam: Camera, bits: list[int]) -> dict:
    """Per key bits: (mean, 99.9th percentile) of |quantised - exact| over one full frame's 8-bit RGB."""
    images = []
    for sorter, key_size in ((DepthSorter(exact_sort), DEFAULT_BITS), *((DepthSorter(), b) for b in bits)):
        renderer = SplatRenderer(ctx, sorter)
        renderer.sort_bits = key_size
        renderer.set_scene(arrays)
        fbo = ctx.framebuffer([ctx.texture((cam.width, cam.height), 4)])
        renderer.render(cam, fbo, BACKGROUND)
        images.append(read_rgb(fbo).astype(np.int16))
        fbo.color_attachments[0].release()
        fbo.release()
        renderer.release()
    diffs = [np.abs(image - images[0]) for image in images[1:]]
    return {b: (float(d.mean()), float(np.percentile(d, 99.9))) for b, d in zip(bits, diffs, strict=True)}


def frame_loop(ctx: moderngl.Context, renderer: SplatRenderer, control: CameraControl, size: tuple[int, int],
               seconds: float, fps: float) -> dict:
    """Orbit (at least 1 s and 20 frames to let the governor settle, then ``seconds`` measured), then stay still
    ``seconds``, through the studio's paced view at its frame cap: frame intervals (ms) of both, the moving frames'
    drawn shares and waits for a sort."""
    target = ctx.framebuffer([ctx.texture(size, 4)])
    view = SceneView(ctx)
    passes = [ViewPass(renderer, "diffuse")]
    period = 1.0 / fps if fps > 0 else 0.0
    out: dict = {"orbiting": [], "still": [], "shares": [], "waits": []}
    for phase, span, moving in (("settle", 1.0, True), ("orbiting", seconds, True), ("still", seconds, False)):
        end, last, deadline, count = time.perf_counter() + span, None, time.perf_counter(), 0
        while (start := time.perf_counter()) < end or (phase == "settle" and count < 20):
            count += 1
            if last is not None and phase != "settle":
                out[phase].append((start - last) * 1e3)
            last = start
            if moving:
                control.orbit(4.0, 0.0)
            view.draw(target, control.camera(*size), passes, ("bench",), BACKGROUND)
            ctx.finish()
            if phase == "orbiting":
                out["shares"].append(view.stats.last_detail)
                out["waits"].append(renderer.last_wait_ms)
            if period:
                deadline = max(deadline + period, time.perf_counter() - period)
                time.sleep(max(0.0, deadline - time.perf_counter()))
    out.update(builds=view.stats.builds_completed, no_order=view.stats.no_order,
               **still_cost(ctx, view, renderer, control.camera(*size), target))
    view.release()
    target.color_attachments[0].release()
    target.release()
    return out


def still_cost(ctx: moderngl.Context, view: SceneView, renderer: SplatRenderer, cam: Camera,
               target: moderngl.Framebuffer, frames: int = 30) -> dict:
    """A still camera once its image is built: the median work (ms) of a frame (draw + finish) and the sorts it
    submitted."""
    while view.building:  # the build of the still view, frame by frame
        view.draw(target, cam, [ViewPass(renderer, "diffuse")], ("bench",), BACKGROUND)
    submitted, work = renderer.sorter.stats.submitted, []
    for _ in range(frames):
        t0 = time.perf_counter()
        view.draw(target, cam, [ViewPass(renderer, "diffuse")], ("bench",), BACKGROUND)
        ctx.finish()
        work.append((time.perf_counter() - t0) * 1e3)
    return {"still_built_ms": float(np.median(work)), "still_sorts": renderer.sorter.stats.submitted - submitted}


def gl_bytes(renderer: SplatRenderer) -> int:
    """Bytes of the renderer's textures and buffers (on llvmpipe they live in host memory)."""
    textures = [*renderer._geometry, *renderer._layers.values()]
    return (sum(t.width * t.height * 16 for t in textures) + renderer._projected.size
            + renderer._index_buffer.size)


def open_and_draw(ctx: moderngl.Context, scene: GaussianScene, args: argparse.Namespace) -> dict:
    """The viewer opens the scene and draws (orbit, still): timings, memory before/after, the kept arrays."""
    before = rss_bytes()
    renderer = SplatRenderer(ctx)
    t0 = time.perf_counter()
    renderer.set_scene(scene_arrays(scene))
    open_s = time.perf_counter() - t0
    control = orbit_control(scene, *args.size)
    opened = rss_bytes() - before
    frames = frame_loop(ctx, renderer, control, args.size, args.seconds, args.fps)
    frames.update(open_s=open_s, host_bytes=rss_bytes() - before, opened_bytes=opened, gl_bytes=gl_bytes(renderer),
                  array_bytes=renderer._means.nbytes + renderer._by_importance.nbytes + 4 * scene.count,
                  by_importance=renderer._by_importance.copy())
    renderer.release()
    return frames


def load_time(scene: GaussianScene, tmp_dir: str | None) -> tuple[GaussianScene, float, int]:
    """Write ``scene`` to a temporary .ply and read it back: (the scene read, seconds to read it, file bytes)."""
    with tempfile.TemporaryDirectory(dir=tmp_dir) as tmp:
        path = Path(tmp) / "densified.ply"
        save_scene(scene, path)
        del scene
        gc.collect()
        t0 = time.perf_counter()
        loaded, _ = load_scene(path)
        return loaded, time.perf_counter() - t0, path.stat().st_size


def run_size(ctx: moderngl.Context, source: GaussianScene, n: int, args: argparse.Namespace) -> dict:
    """Every figure of one size (see the module docstring)."""
    scene, load_s, file_bytes = load_time(densify(source, n), args.tmp)
    drawn = open_and_draw(ctx, scene, args)
    share = float(np.median(drawn["shares"]))
    subset = drawn.pop("by_importance")[: max(1, math.ceil(share * n))] if share < 1.0 else None
    views = orbit_views(orbit_control(scene, *args.size), *args.size, args.views)
    sorts = sort_times(scene.means, views, subset)
    bits = sorted({DEFAULT_BITS, key_bits(n)})
    quality = {b: inversion_buckets(scene.means, views[0], b) for b in bits}
    diff = image_difference(ctx, scene_arrays(scene), views[1], bits)
    return {"n": n, "file_mb": file_bytes / 2**20, "load_s": load_s, "share": share, "sorts": sorts,
            "quality": quality, "diff": diff, **drawn}


def stats(ms: list[float]) -> str:
    """``fps (median) / p95 ms`` of frame intervals."""
    if not ms:
        return "-"
    return f"{1e3 / np.median(ms):.1f} / {np.percentile(ms, 95):.1f}"


def report(rows: list[dict]) -> None:
    """The three tables and the RESULT lines."""
    names = list(dict.fromkeys(k for r in rows for k in r["sorts"]))
    print("\nsort, ms (median over the orbit's views; old = numpy argsort of float64 depths, on the UI thread; "
          "key_bits(n) = log2(n / 4) clamped to 10-20; moving subset: the Gaussians the orbit drew)")
    print("| Gaussians | key_bits(n) | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 2) + "|")
    for r in rows:
        cells = " | ".join(f"{r['sorts'][k]:.1f}" if k in r["sorts"] else "-" for k in names)
        print(f"| {r['n']:,} | {key_bits(r['n'])} | {cells} |")
    print("\nquality of the quantised order (out-of-order pairs' largest depth gap, bucket widths; one frame "
          "against the exact order's, 8-bit |difference| mean / 99.9th percentile)")
    print("| Gaussians | largest inverted gap | image difference |")
    print("|---|---|---|")
    for r in rows:
        gaps = ", ".join(f"{bits} bits {gap:.2f}" for bits, gap in r["quality"].items())
        diffs = ", ".join(f"{bits} bits {mean:.4f} / {high:.0f}" for bits, (mean, high) in r["diff"].items())
        print(f"| {r['n']:,} | {gaps} | {diffs} |")
    print("\nviewer (fps median / p95 ms; host memory = live RSS after opening and drawing minus before, per "
          "Gaussian; after opening only / of which GL objects / renderer+sorter arrays)")
    print("| Gaussians | file MB | load s | open s | orbiting | still | still once built: ms a frame, sorts | "
          "drawn while orbiting | frame waited for a sort, ms | host B/G (opened / GL / arrays) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        n = r["n"]
        print(f"| {n:,} | {r['file_mb']:.0f} | {r['load_s']:.2f} | {r['open_s']:.2f} | {stats(r['orbiting'])} | "
              f"{stats(r['still'])} | {r['still_built_ms']:.2f}, {r['still_sorts']} | {r['share']:.3f} | "
              f"{max(r['waits'], default=0.0):.1f} | "
              f"{r['host_bytes'] / n:.0f} ({r['opened_bytes'] / n:.0f} / {r['gl_bytes'] / n:.0f} / "
              f"{r['array_bytes'] / n:.0f}) |")
    for r in rows:
        print(f"RESULT n={r['n']} sort_ms={r['sorts'][f'numba {DEFAULT_BITS} bits']:.1f} "
              f"frame_blocked_by_sort_ms={max(r['waits'], default=0.0):.1f} drawn_share_orbiting={r['share']:.3f} "
              f"load_s={r['load_s']:.2f} host_bytes_per_gaussian={r['host_bytes'] / r['n']:.0f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", default="200000,1200000,3000000,6000000",
                   help="comma-separated Gaussian counts")
    p.add_argument("--source", default=str(SOURCE), help="the real capture to densify")
    p.add_argument("--seconds", type=float, default=4.0, help="seconds measured orbiting, and again still")
    p.add_argument("--size", type=parse_size, default=(800, 600))
    p.add_argument("--fps", type=float, default=60.0, help="the frame cap (the studio's default is 60)")
    p.add_argument("--views", type=int, default=6, help="orbit views the sorts are timed on")
    p.add_argument("--tmp", default=None, help="folder for the temporary .ply (default: the system's)")
    args = p.parse_args()
    sizes = [int(float(s)) for s in args.sizes.split(",") if s.strip()]
    print(f"cpu: {cpu_description()}; {os.cpu_count()} cores; {args.size[0]}x{args.size[1]}, cap {args.fps:g} fps")
    source, _ = load_scene(args.source)
    depth_order(source.means[:16], np.eye(4), NEAR)  # numba's kernel loaded (compiled once) before measuring
    ctx = moderngl.create_standalone_context(backend="egl", require=330)
    rows = []
    for n in sizes:
        t0 = time.perf_counter()
        rows.append(run_size(ctx, source, n, args))
        print(f"{n:,} Gaussians measured in {time.perf_counter() - t0:.0f} s; peak RSS so far "
              f"{peak_rss_gb():.1f} GB", flush=True)
    report(rows)
    ctx.release()


def peak_rss_gb() -> float:
    """The process's peak resident memory (GB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


if __name__ == "__main__":
    main()
