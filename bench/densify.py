"""Larger captures made from a real one: each Gaussian replaced by children sampled inside it, as a denser capture
of the same surfaces looks (seeded). ``viewer_scale.py`` and ``engine_scale.py`` build their scenes with it, and
``tests/test_capture_scale.py`` its 200k scene from the demo.

``densify(scene, n)`` copies each Gaussian k = ceil(n / count) times (the first n copies kept), moves every copy by
a jitter drawn within the Gaussian's own ellipsoid (a normal of 0.5 sigma along each of its axes) and shrinks its
scales by k^(-1/3), so the copies fill the original's volume. With k = 1 (n at most the capture's count) the first n
Gaussians are kept as they are: a part of the real capture, not a jittered copy.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from app.splat_data import rotation_matrices  # noqa: E402
from gstyle_core.scene import GaussianScene  # noqa: E402

CHUNK = 1 << 20  # Gaussians jittered at a time: [CHUNK, 3, 3] float64 rotations


def densify(scene: GaussianScene, n: int, seed: int = 0) -> GaussianScene:
    """``n`` Gaussians from ``scene``: copies moved within their own ellipsoid, scales shrunk by k^(-1/3) (module
    docstring); the capture's first ``n`` rows unchanged when ``n`` is at most its count. SH bands are dropped (the
    engine keeps only the diffuse colour)."""
    if n < 1:
        raise ValueError(f"densify: n must be at least 1, got {n}")
    k = math.ceil(n / scene.count)
    index = np.tile(np.arange(scene.count), k)[:n]
    means = scene.means[index].astype(np.float32, copy=True)
    if k > 1:
        rng = np.random.default_rng(seed)
        for start in range(0, n, CHUNK):
            part = index[start:start + CHUNK]
            scales = np.exp(scene.log_scales[part].astype(np.float64))
            jitter = rng.normal(0, 0.5, (part.size, 3)) * scales  # along the Gaussian's own axes
            means[start:start + CHUNK] += np.einsum("nij,nj->ni", rotation_matrices(scene.quats[part]), jitter)
    shrink = np.float32(math.log(k) / 3)
    return GaussianScene(means, scene.log_scales[index] - shrink, scene.quats[index].copy(),
                         scene.opacity_logits[index].copy(), scene.sh_dc[index].copy(),
                         np.zeros((n, 0, 3), np.float32))
