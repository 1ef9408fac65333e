"""Peak memory per Gaussian of a stylization run (the estimate behind the default ``max_gaussians``).

Usage: .venv/bin/python bench/bench_memory_per_gaussian.py [--width W] [--device D] [COPIES ...]
(default 192 px, cpu, 1 4)

Each measurement runs in a fresh process: the bundled demo scene replicated COPIES times (each copy jittered by a
fraction of the Gaussian sizes, so the footprint per Gaussian stays that of a real scene), generated cameras,
preview settings at 192 px (16 views), a cheap stand-in objective (the networks' memory does not depend on the
Gaussian count), driven through ground truth, one pre-processing round (split + 3 refit iterations), one
stylization epoch (every view's colour cache built) and one colour-gradient split with 3 refit iterations.
Reported: peak RSS (``ru_maxrss``) per run, and the slope between the smallest and largest run in bytes per
Gaussian (``RESULT`` line). With ``--device cuda`` the run computes on the GPU (gsplat's colour caches, the refits'
parameters and Adam there) and the GPU's peaks are reported beside the RSS: torch's allocated and reserved bytes
(``max_memory_allocated`` / ``max_memory_reserved``), with their slopes per Gaussian (``RESULT`` line
``gpu_bytes_per_gaussian``, the figure a cap on Gaussians from a card's memory needs).
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def replicated_demo(copies: int):
    """The bundled demo scene ``copies`` times (each copy but the first jittered by a fraction of its Gaussians'
    sizes, so the footprint per Gaussian stays that of a real scene) and its generated cameras."""
    sys.path.insert(0, str(ROOT))
    import numpy as np

    from gstyle_core.scene import GaussianScene
    from gstyle_core.scene_images import load_scene_and_cameras

    scene, _report, cams = load_scene_and_cameras(None, None)
    rng = np.random.default_rng(0)
    parts = []
    for i in range(copies):
        jitter = rng.normal(0, 0.3, scene.means.shape) * np.exp(scene.log_scales) if i else 0.0
        parts.append(scene.means + jitter)
    big = GaussianScene(np.concatenate(parts).astype(np.float32), np.tile(scene.log_scales, (copies, 1)),
                        np.tile(scene.quats, (copies, 1)), np.tile(scene.opacity_logits, copies),
                        np.tile(scene.sh_dc, (copies, 1)), np.tile(scene.sh_rest, (copies, 1, 1)))
    return big, cams.cameras


def child(copies: int, width: int, device: str = "cpu") -> dict:
    """Run the stylization in this process on ``device``; return the Gaussian count and the peaks of RSS (and of
    the GPU's memory on CUDA)."""
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "tests"))
    import numpy as np
    import torch
    from fakes import MeanColourPull

    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer
    from gstyle_core.machine import set_torch_threads

    set_torch_threads(1)
    big, cameras = replicated_demo(copies)
    settings = resolve_settings("preview", "360", len(cameras), refit_iterations=3, epochs=2.0, min_steps=0,
                                split_at=(1 / 3,), preprocess_rounds=1,
                                working_width=width, device=device)
    style = np.random.default_rng(1).uniform(0, 1, (64, 64, 3)).astype(np.float32)
    engine = Stylizer(big, cameras, style, settings, objective_factory=MeanColourPull)
    phases = set()
    while engine.phase not in ("finish", "done") and engine.global_step < 10_000:
        phases.add(engine.step().phase)
        if "refit" in phases and engine.phase == "stylize":
            break
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: KiB
    gpu = {}
    if device == "cuda":
        torch.cuda.synchronize()
        gpu = {"gpu_allocated": torch.cuda.max_memory_allocated(), "gpu_reserved": torch.cuda.max_memory_reserved(),
               "card": torch.cuda.get_device_name(0)}
    return {"gaussians_in": big.count, "gaussians_out": engine.gaussian_count, "peak_rss": peak,
            "phases": sorted(phases), "views": len(engine.cameras), "width": settings.working_width,
            "device": device, **gpu}


def _slope(rows: list[dict], key: str) -> float:
    """Bytes per Gaussian of ``key`` between the smallest and the largest run."""
    lo, hi = rows[0], rows[-1]
    return (hi[key] - lo[key]) / max(1, hi["gaussians_out"] - lo["gaussians_out"])


def main(argv: list[str]) -> int:
    width, device = 192, "cpu"
    while argv[:1] in (["--width"], ["--device"]):
        if argv[0] == "--width":
            width = int(argv[1])
        else:
            device = argv[1]
        argv = argv[2:]
    if argv[:1] == ["--child"]:
        print(json.dumps(child(int(argv[1]), int(argv[2]), argv[3] if len(argv) > 3 else "cpu")))
        return 0
    copies = [int(a) for a in argv] or [1, 4]
    rows = []
    for c in copies:
        out = subprocess.run([sys.executable, __file__, "--child", str(c), str(width), device], capture_output=True,
                             text=True, check=True, cwd=ROOT)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        r = rows[-1]
        gpu = (f", GPU peak {r['gpu_allocated'] / 2**20:8.1f} MiB allocated, {r['gpu_reserved'] / 2**20:8.1f} MiB "
               f"reserved ({r['card']})" if "gpu_allocated" in r else "")
        print(f"copies {c}: {r['gaussians_in']:>8,} -> {r['gaussians_out']:>8,} Gaussians, {r['views']} views at "
              f"{r['width']} px on {device}, peak RSS {r['peak_rss'] / 2**20:8.1f} MiB{gpu}  "
              f"(phases {', '.join(r['phases'])})")
    lo, hi = rows[0], rows[-1]
    span = f"between {lo['gaussians_out']:,} and {hi['gaussians_out']:,} Gaussians at {width} px"
    print(f"RESULT bytes_per_gaussian={_slope(rows, 'peak_rss'):.0f} (peak RSS slope {span})")
    if "gpu_allocated" in hi:
        print(f"RESULT gpu_bytes_per_gaussian={_slope(rows, 'gpu_allocated'):.0f} "
              f"gpu_reserved_bytes_per_gaussian={_slope(rows, 'gpu_reserved'):.0f} (GPU peak slopes {span})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
