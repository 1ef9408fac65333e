"""The viewer at 0.2-6 M Gaussians: the depth sort off the frame, frame rates, load time and host memory.

Scenes are built by densifying a real capture (``biker.spz``, 152,746 Gaussians; ``densify.py``): each Gaussian is
copied k = ceil(n / 152,746) times, every copy moved within the Gaussian's own ellipsoid and its scales shrunk by
k^(-1/3), so the copies fill the original's volume as a denser capture would. Per size:

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
* frames and memory, once per texture layout of the renderer ("compact", the default, and "float32", the layout
  before it; ``splat_data.LAYOUTS``), each in a fresh process that reads the .ply (so that neither inherits the
  other's allocator or GL driver state): resident memory (Linux /proc) after the viewer opened the scene and drew
  (orbit and still) minus before, per Gaussian, once freed heap memory went back to the system (glibc's
  malloc_trim: what is live) and as it was (what the allocator kept besides); the renderer's GL objects by part
  (``SplatRenderer.gl_memory``; on llvmpipe they live in host memory) and the arrays the renderer and its sorter
  keep; the rest is the GL driver's working memory (llvmpipe's binned scenes, its compiled shaders) and the
  process's other caches. Beside them, one frame of each layout against the other (8-bit |difference|).

    .venv/bin/python bench/viewer_scale.py [--sizes 1200000,6000000] [--seconds 4] [--size 800x600] [--fps 60]

Ends with one line per size: ``RESULT n=… sort_ms=… frame_blocked_by_sort_ms=… drawn_share_orbiting=… load_s=…
host_bytes_per_gaussian=…`` (sort_ms: the new sort of all n, ``DEFAULT_BITS`` keys, off the UI thread).
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import moderngl  # noqa: E402
from densify import densify  # noqa: E402

from app.camera_control import CameraControl  # noqa: E402
from app.depth_sort import (  # noqa: E402
    DEFAULT_BITS,
    DepthSorter,
    SortScratch,
    depth_order,
    exact_sort_request,
    key_bits,
)
from app.gl_io import read_rgb  # noqa: E402
from app.main import parse_size  # noqa: E402
from app.renderer import NEAR, SplatRenderer  # noqa: E402
from app.scene_view import SceneView, ViewPass  # noqa: E402
from app.splat_data import (  # noqa: E402
    LAYOUTS,
    back_to_front_order,
    importance_order,
    scene_arrays,
)
from gstyle_core.cameras.camera import Camera  # noqa: E402
from gstyle_core.cameras.framing import scene_box  # noqa: E402
from gstyle_core.cameras.generate import finite_points, robust_centre_radius  # noqa: E402
from gstyle_core.io import load_scene, save_scene  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402
from gstyle_core.scene import GaussianScene  # noqa: E402

SOURCE = ROOT.parent / "shared" / "data" / "scenes" / "playcanvas" / "biker.spz"
BACKGROUND = (0.1, 0.1, 0.12)


def rss_bytes(trim: bool = True) -> int:
    """Resident memory of this process (Linux /proc); with ``trim`` once freed heap memory went back to the
    system (glibc's malloc_trim: what is live, not what the allocator kept)."""
    gc.collect()
    if trim:
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


def frame_of(ctx: moderngl.Context, arrays: dict, cam: Camera, sorter: DepthSorter, bits: int = DEFAULT_BITS,
             layout: str = "compact") -> np.ndarray:
    """One full 8-bit frame (int16 RGB) of the viewer with this sorter, key bits and texture layout."""
    renderer = SplatRenderer(ctx, sorter, layout=layout)
    renderer.sort_bits = bits
    renderer.set_scene(arrays)
    fbo = ctx.framebuffer([ctx.texture((cam.width, cam.height), 4)])
    renderer.render(cam, fbo, BACKGROUND)
    image = read_rgb(fbo).astype(np.int16)
    fbo.color_attachments[0].release()
    fbo.release()
    renderer.release()
    return image


def image_difference(ctx: moderngl.Context, arrays: dict, cam: Camera, bits: list[int]) -> dict:
    """(mean, 99.9th percentile) of the 8-bit |difference| over one full frame: per key bits, the quantised order
    against the exact one; "float32": the float32 texture layout against the compact one (both exactly sorted)."""
    exact = frame_of(ctx, arrays, cam, DepthSorter(exact_sort_request))
    diffs = {b: np.abs(frame_of(ctx, arrays, cam, DepthSorter(), b) - exact) for b in bits}
    diffs["float32"] = np.abs(frame_of(ctx, arrays, cam, DepthSorter(exact_sort_request), layout="float32") - exact)
    return {key: (float(d.mean()), float(np.percentile(d, 99.9))) for key, d in diffs.items()}


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


def malloc_live() -> int:
    """Bytes glibc's malloc has handed out and not taken back (mallinfo2; 0 where there is none)."""
    class MallInfo2(ctypes.Structure):
        _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                          "fsmblks", "uordblks", "fordblks", "keepcost")]

    try:
        mallinfo2 = ctypes.CDLL("libc.so.6").mallinfo2
    except (OSError, AttributeError):
        return 0
    mallinfo2.restype = MallInfo2
    info = mallinfo2()
    return int(info.uordblks + info.hblkhd)


def open_and_draw(ctx: moderngl.Context, scene: GaussianScene, args: argparse.Namespace) -> dict:
    """The viewer (``args.layout``) opens the scene and draws (orbit, still): timings, memory before/after (live,
    as the allocator left it, malloc's own count), its GL objects by part and the arrays it keeps."""
    before, before_raw, before_live = rss_bytes(), rss_bytes(trim=False), malloc_live()
    renderer = SplatRenderer(ctx, layout=args.layout)
    if args.draw_chunk is not None:
        renderer.draw_chunk = args.draw_chunk
    t0 = time.perf_counter()
    renderer.set_scene(scene_arrays(scene))
    open_s = time.perf_counter() - t0
    opened_raw = rss_bytes(trim=False) - before_raw
    control = orbit_control(scene, *args.size)
    opened = rss_bytes() - before
    frames = frame_loop(ctx, renderer, control, args.size, args.seconds, args.fps)
    host_raw = rss_bytes(trim=False) - before_raw
    frames.update(open_s=open_s, host_bytes=rss_bytes() - before, host_raw_bytes=host_raw, opened_bytes=opened,
                  opened_raw_bytes=opened_raw, malloc_bytes=malloc_live() - before_live, gl=renderer.gl_memory(),
                  array_bytes=renderer._means.nbytes + renderer._by_importance.nbytes + 4 * scene.count)
    renderer.release()
    return frames


def viewer_child(args: argparse.Namespace) -> None:
    """``--viewer PLY``: read the scene, open and draw it in ``args.layout``, print one ``VIEWER {json}`` line."""
    scene, _ = load_scene(args.viewer)
    depth_order(scene.means[:16], np.eye(4), NEAR)  # numba's kernel loaded before measuring
    ctx = moderngl.create_standalone_context(backend="egl", require=330)
    print("VIEWER " + json.dumps(open_and_draw(ctx, scene, args)), flush=True)


def viewer_in_child(path: Path, layout: str, args: argparse.Namespace) -> dict:
    """``open_and_draw`` of the .ply at ``path`` in ``layout``, in a fresh process."""
    command = [sys.executable, str(Path(__file__).resolve()), "--viewer", str(path), "--layout", layout,
               "--seconds", str(args.seconds), "--size", f"{args.size[0]}x{args.size[1]}", "--fps", str(args.fps)]
    if args.draw_chunk is not None:
        command += ["--draw-chunk", str(args.draw_chunk)]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    lines = [line for line in done.stdout.splitlines() if line.startswith("VIEWER ")]
    if done.returncode != 0 or not lines:
        raise SystemExit(f"the {layout} viewer of {path.name} failed: {done.stderr.strip()[-2000:]}")
    return json.loads(lines[-1][len("VIEWER "):])


def run_size(ctx: moderngl.Context, source: GaussianScene, n: int, args: argparse.Namespace) -> dict:
    """Every figure of one size (see the module docstring)."""
    with tempfile.TemporaryDirectory(dir=args.tmp) as tmp:
        path = Path(tmp) / "densified.ply"
        save_scene(densify(source, n), path)
        gc.collect()
        t0 = time.perf_counter()
        scene, _ = load_scene(path)
        load_s, file_bytes = time.perf_counter() - t0, path.stat().st_size
        viewers = {layout: viewer_in_child(path, layout, args) for layout in LAYOUTS}
    share = float(np.median(viewers["compact"]["shares"]))
    ranked = importance_order(scene.log_scales, scene.opacity_logits)
    subset = ranked[: max(1, math.ceil(share * n))] if share < 1.0 else None
    views = orbit_views(orbit_control(scene, *args.size), *args.size, args.views)
    sorts = sort_times(scene.means, views, subset)
    bits = sorted({DEFAULT_BITS, key_bits(n)})
    quality = {b: inversion_buckets(scene.means, views[0], b) for b in bits}
    diff = image_difference(ctx, scene_arrays(scene), views[min(1, len(views) - 1)], bits)
    return {"n": n, "file_mb": file_bytes / 2**20, "load_s": load_s, "share": share, "sorts": sorts,
            "quality": quality, "diff": diff, "viewers": viewers}


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
        diffs = ", ".join(f"{bits} bits {mean:.4f} / {high:.0f}" for bits, (mean, high) in r["diff"].items()
                          if bits != "float32")
        print(f"| {r['n']:,} | {gaps} | {diffs} |")
    print("\nviewer, per texture layout, each in its own process (fps median / p95 ms). Host memory per Gaussian: "
          "RSS after opening and drawing minus before, live (freed heap returned first, malloc_trim) and as the "
          "allocator left it; of the live bytes, the renderer's GL objects (geometry / colour layers / projection "
          "output + index buffer), the arrays it and its sorter keep, and the rest (the GL driver's working "
          "memory, caches). Layouts: one frame of float32 against compact, 8-bit |difference| mean / 99.9th pct")
    print("| Gaussians | file MB | load s | layout | open s | orbiting | still | still once built: ms a frame, sorts | "
          "drawn while orbiting | frame waited for a sort, ms | host B/G live (after opening) | as left (after "
          "opening) | GL B/G | arrays | rest | layouts' image difference |")
    print("|---" * 16 + "|")
    for r in rows:
        n = r["n"]
        for layout, v in r["viewers"].items():
            gl = v["gl"]
            gl_total = sum(gl.values())
            rest = v["host_bytes"] - gl_total - v["array_bytes"]
            mean, high = r["diff"]["float32"]
            print(f"| {n:,} | {r['file_mb']:.0f} | {r['load_s']:.2f} | {layout} | {v['open_s']:.2f} | "
                  f"{stats(v['orbiting'])} | {stats(v['still'])} | {v['still_built_ms']:.2f}, {v['still_sorts']} | "
                  f"{float(np.median(v['shares'])):.3f} | {max(v['waits'], default=0.0):.1f} | "
                  f"{v['host_bytes'] / n:.0f} ({v['opened_bytes'] / n:.0f}) | "
                  f"{v['host_raw_bytes'] / n:.0f} ({v['opened_raw_bytes'] / n:.0f}) | "
                  f"{gl_total / n:.0f} ({gl['geometry'] / n:.0f} / {(gl['colours'] + gl['sh']) / n:.0f} / "
                  f"{(gl['projected'] + gl['order']) / n:.0f}) | {v['array_bytes'] / n:.0f} | {rest / n:.0f} | "
                  f"{mean:.4f} / {high:.0f} |")
    for r in rows:
        v = r["viewers"]["compact"]
        print(f"RESULT n={r['n']} sort_ms={r['sorts'][f'numba {DEFAULT_BITS} bits']:.1f} "
              f"frame_blocked_by_sort_ms={max(v['waits'], default=0.0):.1f} drawn_share_orbiting={r['share']:.3f} "
              f"load_s={r['load_s']:.2f} host_bytes_per_gaussian={v['host_bytes'] / r['n']:.0f}")


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
    p.add_argument("--draw-chunk", type=int, default=None,
                   help="splats a draw call (0: one call; default: the renderer's, 32768 on llvmpipe)")
    p.add_argument("--viewer", default=None, help=argparse.SUPPRESS)  # the child process of one layout's viewer
    p.add_argument("--layout", default="compact", choices=LAYOUTS, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.viewer:
        viewer_child(args)
        return
    if args.views < 1:
        p.error(f"--views must be at least 1, got {args.views}")
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
              f"{peak_rss_gb():.1f} GB (a viewer process: {peak_rss_gb(children=True):.1f} GB)", flush=True)
    report(rows)
    ctx.release()


def peak_rss_gb(children: bool = False) -> float:
    """Peak resident memory (GB) of this process, or of its largest child process so far."""
    import resource

    who = resource.RUSAGE_CHILDREN if children else resource.RUSAGE_SELF
    return resource.getrusage(who).ru_maxrss / 2**20


if __name__ == "__main__":
    main()
