"""Benchmark the CPU rasterizer: fast vs reference backend, colour-only cache, and the ratio to VGG-16.

Run: ``.venv/bin/python bench/raster.py [--threads 2] [--quick]``. Prints where it ran (the CPU's model and flags,
the threads, the precision ``--precision auto`` picks here and why), a table and, last, the line
``RESULT speedup_vs_reference=X raster_over_vgg=Y raster_over_vgg_bf16=Z precision=P`` measured side by side on a
fixed-seed random 50k subset of shared/data/scenes/splat/winter_fountain.cropped.splat seen whole at 256x256,
forward+backward. The floor is VGG-16 conv1_1…relu3_3 forward+backward at both precisions: fp32 (``Y``, the figure
of earlier rounds) and bf16 channels_last as ``--precision bf16`` runs it (``Z``).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gstyle_core.machine import cpu_description  # noqa: E402
from gstyle_core.raster import ColourCache, rasterize  # noqa: E402
from gstyle_core.style.precision import choose_precision, working_size  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
SPLAT = DATA / "scenes" / "splat" / "winter_fountain.cropped.splat"
SPLAT_RECORD = 32


def read_splat(path: Path) -> dict[str, np.ndarray]:
    """Private .splat reader: position f32x3, linear scale f32x3, RGBA u8x4, rotation u8x4 (wxyz)."""
    raw = path.read_bytes()
    if len(raw) % SPLAT_RECORD:
        raise ValueError(f"{path}: size {len(raw)} is not a multiple of {SPLAT_RECORD} bytes")
    dt = np.dtype([("pos", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4), ("rot", "u1", 4)])
    rec = np.frombuffer(raw, dtype=dt)
    return {
        "means": rec["pos"].astype(np.float32),
        "scales": rec["scale"].astype(np.float32),
        "colors": rec["rgba"][:, :3].astype(np.float32) / 255.0,
        "opacities": rec["rgba"][:, 3].astype(np.float32) / 255.0,
        "quats": (rec["rot"].astype(np.float32) - 128.0) / 128.0,
    }


def load_gaussians(path: Path) -> dict[str, np.ndarray]:
    """Use the team's scene reader when it exists, else the private .splat reader."""
    try:
        from gstyle_core.io import load_scene  # type: ignore[attr-defined]
    except ImportError:
        return read_splat(path)
    loaded = load_scene(path)
    scene = loaded[0] if isinstance(loaded, tuple) else loaded  # (GaussianScene, LoadReport)
    return {
        "means": scene.means,
        "scales": scene.scales,
        "colors": np.clip(scene.rgb, 0, 1),
        "opacities": scene.opacities,
        "quats": scene.quats,
    }


def framing_camera(means: np.ndarray, size: int, fov_deg: float = 50.0) -> tuple[torch.Tensor, torch.Tensor]:
    """A camera looking along world +z at the means' centre (0.5-99.5 percentile box), framing all."""
    lo, hi = np.percentile(means, 0.5, axis=0), np.percentile(means, 99.5, axis=0)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    half_fov = math.radians(fov_deg) / 2
    distance = radius / math.sin(half_fov)
    viewmat = torch.eye(4)
    viewmat[:3, 3] = torch.tensor(-(centre - np.array([0.0, 0.0, distance])), dtype=torch.float32)
    f = 0.5 * size / math.tan(half_fov)
    K = torch.tensor([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1]], dtype=torch.float32)
    return viewmat, K


def random_gaussians(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Random Gaussians in a unit-ish cube in front of a camera at the origin."""
    rng = np.random.default_rng(seed)
    return {
        "means": (rng.uniform(-1, 1, (n, 3)) + [0, 0, 0]).astype(np.float32),
        "scales": np.exp(rng.uniform(np.log(0.004), np.log(0.03), (n, 3))).astype(np.float32),
        "colors": rng.uniform(0, 1, (n, 3)).astype(np.float32),
        "opacities": rng.uniform(0.05, 1, n).astype(np.float32),
        "quats": rng.normal(size=(n, 4)).astype(np.float32),
    }


def median_time(fn: Callable[[], None], repeats: int, warmup: int = 1) -> float:
    """Median wall time of fn over repeats, after warm-up calls."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def render_fn(
    g: dict[str, np.ndarray], viewmat, K, size: int, backend: str, backward: bool
) -> Callable[[], None]:
    """A closure that renders (and back-propagates a random-weight loss when backward=True)."""
    params = {k: torch.from_numpy(v) for k, v in g.items()}
    for p in params.values():
        p.requires_grad_(backward)
    weight = torch.rand(size, size, 3, generator=torch.Generator().manual_seed(1))

    def run() -> None:
        out = rasterize(
            params["means"],
            params["quats"],
            params["scales"],
            params["opacities"],
            params["colors"],
            viewmat,
            K,
            size,
            size,
            backend=backend,
        )
        if backward:
            (out.image * weight).sum().backward()
            for p in params.values():
                p.grad = None

    return run


def vgg_slice() -> torch.nn.Sequential:
    """VGG-16 conv1_1 ... relu3_3 with random weights (timing does not depend on the weights)."""
    layers: list[torch.nn.Module] = []
    channels = 3
    for block, (width, convs) in enumerate([(64, 2), (128, 2), (256, 3)]):
        if block:
            layers.append(torch.nn.MaxPool2d(2))
        for _ in range(convs):
            layers += [torch.nn.Conv2d(channels, width, 3, padding=1), torch.nn.ReLU()]
            channels = width
    net = torch.nn.Sequential(*layers)
    for p in net.parameters():
        p.requires_grad_(False)
    return net


def vgg_fn(size: int, bf16: bool = False) -> Callable[[], None]:
    """Forward+backward to the input image (the stylization case: frozen weights); ``bf16``: the network in bfloat16,
    channels_last, the fp32 image cast on the way in and its gradient fp32 (as ``--precision bf16`` runs it)."""
    net = vgg_slice()
    if bf16:
        net = net.to(torch.bfloat16, memory_format=torch.channels_last)
    image = torch.rand(1, 3, size, size, requires_grad=True)

    def run() -> None:
        x = image.to(torch.bfloat16).contiguous(memory_format=torch.channels_last) if bf16 else image
        net(x).float().sum().backward()
        image.grad = None

    return run


def colour_cache_times(g, viewmat, K, size: int, repeats: int) -> tuple[float, float, int]:
    """(build seconds, forward+backward seconds, nnz) of the colour-only path."""
    t = {k: torch.from_numpy(v) for k, v in g.items()}
    t0 = time.perf_counter()
    cache = ColourCache(
        t["means"], t["quats"], t["scales"], t["opacities"], viewmat, K, size, size, geometry_version=0
    )
    build = time.perf_counter() - t0
    colors = t["colors"].clone().requires_grad_(True)
    weight = torch.rand(size, size, 3)

    def run() -> None:
        (cache.render(colors) * weight).sum().backward()
        colors.grad = None

    return build, median_time(run, repeats), int(cache.weights.values().shape[0])


def synthetic_table(repeats: int) -> None:
    """The synthetic table: fast and reference backends and the colour-only cache, 10k/50k random Gaussians."""
    rows = []
    viewmat = torch.eye(4)
    viewmat[2, 3] = 3.0
    for n in (10_000, 50_000):
        g = random_gaussians(n)
        for size in (128, 256, 512):
            K = torch.tensor([[size * 1.2, 0, size / 2], [0, size * 1.2, size / 2], [0, 0, 1]])
            row = {"N": n, "res": size}
            row["fast_fwd"] = median_time(render_fn(g, viewmat, K, size, "fast", False), repeats)
            row["fast_fb"] = median_time(render_fn(g, viewmat, K, size, "fast", True), repeats)
            if n * size * size <= 50_000 * 256 * 256:
                row["ref_fwd"] = median_time(render_fn(g, viewmat, K, size, "reference", False), 2)
                row["ref_fb"] = median_time(render_fn(g, viewmat, K, size, "reference", True), 2)
            row["cc_build"], row["cc_fb"], row["nnz"] = colour_cache_times(
                g, viewmat, K, size, repeats
            )
            rows.append(row)
    cols = ["N", "res", "fast_fwd", "fast_fb", "ref_fwd", "ref_fb", "cc_build", "cc_fb", "nnz"]
    print("times in seconds (median); fb = forward+backward; cc = colour-only cache")
    print(" ".join(f"{c:>9}" for c in cols))
    for row in rows:
        cells = []
        for c in cols:
            v = row.get(c)
            cells.append(f"{'-':>9}" if v is None else f"{v:>9}" if isinstance(v, int) else f"{v:>9.4f}")
        print(" ".join(cells))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--threads", type=int, default=2, help="torch and numba threads")
    parser.add_argument("--quick", action="store_true", help="skip the synthetic table")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--gaussians", type=int, default=50_000, help="Gaussians drawn from the capture")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    print(f"cpu: {cpu_description()}")
    print(f"threads: torch {torch.get_num_threads()}, numba {numba.get_num_threads()}")
    precision, why = choose_precision("auto", working_size(256))
    print(f"precision (--precision auto at 256 px): {why}")

    if not args.quick:
        synthetic_table(args.repeats)

    if not SPLAT.exists():
        print(f"RESULT skipped: {SPLAT} not found")
        return
    g_all = load_gaussians(SPLAT)
    count = min(args.gaussians, len(g_all["means"]))
    idx = np.sort(np.random.default_rng(0).choice(len(g_all["means"]), count, replace=False))
    g = {k: np.ascontiguousarray(v[idx]) for k, v in g_all.items()}
    size = 256
    viewmat, K = framing_camera(g["means"], size)
    fast = render_fn(g, viewmat, K, size, "fast", True)
    ref = render_fn(g, viewmat, K, size, "reference", True)
    fns = (fast, ref, vgg_fn(size), vgg_fn(size, bf16=True))
    times: list[list[float]] = [[] for _ in fns]
    for fn in fns:
        fn()  # warm-up
    for _ in range(args.repeats):  # interleaved, so machine load hits all alike
        for fn, acc in zip(fns, times, strict=True):
            t0 = time.perf_counter()
            fn()
            acc.append(time.perf_counter() - t0)
    tf, tr, tv, tb = (statistics.median(t) for t in times)
    out = rasterize(
        *(torch.from_numpy(g[k]) for k in ("means", "quats", "scales", "opacities", "colors")),
        viewmat,
        K,
        size,
        size,
    )
    print(
        f"winter_fountain {count:,} @256^2: {out.stats['visible']} visible, {out.stats['tile_pairs']} tile pairs; "
        f"fast {tf:.4f}s, reference {tr:.4f}s, VGG {tv:.4f}s fp32 / {tb:.4f}s bf16 (forward+backward, median of "
        f"{args.repeats})"
    )
    print(f"RESULT speedup_vs_reference={tr / tf:.2f} raster_over_vgg={tf / tv:.3f} raster_over_vgg_bf16={tf / tb:.3f} "
          f"precision={precision}")


if __name__ == "__main__":
    main()
