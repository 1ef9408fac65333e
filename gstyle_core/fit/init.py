"""Initial Gaussians for fitting: from sparse points (COLMAP) or random points in the cameras' view."""

from __future__ import annotations

import numpy as np
import torch

from ..scene import GaussianScene, logit, rgb_to_sh_dc


def mean_knn_distance(points: np.ndarray, k: int = 3, chunk: int = 2048) -> np.ndarray:
    """Mean distance of each point to its ``k`` nearest other points (chunked, memory bounded)."""
    pts = torch.as_tensor(np.asarray(points, np.float32))
    n = len(pts)
    if n <= 1:
        return np.full(n, 1.0, np.float32)
    k = min(k, n - 1)
    out = torch.empty(n)
    for i in range(0, n, chunk):
        d = torch.cdist(pts[i : i + chunk], pts)
        d[torch.arange(d.shape[0]), torch.arange(i, i + d.shape[0])] = float("inf")
        out[i : i + chunk] = d.topk(k, largest=False).values.mean(dim=1)
    return out.numpy()


def scene_from_points(points: np.ndarray, colors: np.ndarray | None, sh_degree: int = 3,
                      initial_opacity: float = 0.1) -> GaussianScene:
    """Isotropic Gaussians at ``points`` with the 3DGS initial scale (mean distance to the 3 nearest neighbours)."""
    points = np.asarray(points, np.float32)
    n = len(points)
    if colors is None:
        colors = np.full((n, 3), 0.5, np.float32)
    dist = np.clip(mean_knn_distance(points), 1e-7, None)
    k = (sh_degree + 1) ** 2 - 1
    quats = np.zeros((n, 4), np.float32)
    quats[:, 0] = 1.0
    return GaussianScene(
        means=points.copy(),
        log_scales=np.repeat(np.log(dist)[:, None], 3, axis=1).astype(np.float32),
        quats=quats,
        opacity_logits=np.full(n, logit(np.array(initial_opacity)), np.float32),
        sh_dc=rgb_to_sh_dc(np.asarray(colors, np.float32)),
        sh_rest=np.zeros((n, k, 3), np.float32),
    )


def random_points_in_view(cameras, count: int, near: float, far: float, seed: int = 0) -> np.ndarray:
    """Random points inside the cameras' frusta between depths ``near`` and ``far`` (when no sparse points exist)."""
    rng = np.random.default_rng(seed)
    pts = []
    per_cam = max(1, count // max(1, len(cameras)))
    for cam in cameras:
        u = rng.uniform(0, cam.width, per_cam)
        v = rng.uniform(0, cam.height, per_cam)
        z = rng.uniform(near, far, per_cam)
        xc = np.stack([(u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z, np.ones_like(z)], axis=1)
        pts.append((xc @ cam.cam_to_world.T)[:, :3])
    return np.concatenate(pts).astype(np.float32)[:count]
