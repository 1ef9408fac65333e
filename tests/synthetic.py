"""Small synthetic scenes and cameras for tests (no shared data needed)."""

from __future__ import annotations

import numpy as np

from gstyle_core.cameras.camera import Camera
from gstyle_core.scene import GaussianScene, logit, rgb_to_sh_dc


def look_at_camera(eye, target, width=48, height=40, fov_deg=50.0, up=(0.0, -1.0, 0.0), name="") -> Camera:
    """A pinhole camera at ``eye`` looking at ``target`` (OpenCV axes, world up = -y by default)."""
    eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, -up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = x, y, z, eye
    f = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    return Camera(width, height, f, f, width / 2, height / 2, np.linalg.inv(c2w), name)


def ring_cameras(n=6, radius=3.0, width=48, height=40) -> list[Camera]:
    """Cameras on a ring around the origin, slightly above it."""
    out = []
    for i in range(n):
        a = 2 * np.pi * i / n
        eye = (radius * np.sin(a), -0.5, -radius * np.cos(a))
        out.append(look_at_camera(eye, (0, 0, 0), width, height, name=f"ring{i}"))
    return out


def blob_scene(n=300, seed=0, sh_degree=0, spread=0.6, scale=0.06) -> GaussianScene:
    """Random coloured Gaussians in a ball around the origin."""
    rng = np.random.default_rng(seed)
    means = rng.normal(0, spread, (n, 3)).astype(np.float32)
    log_scales = np.log(rng.uniform(0.5, 1.5, (n, 3)) * scale).astype(np.float32)
    quats = rng.normal(size=(n, 4)).astype(np.float32)
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    k = (sh_degree + 1) ** 2 - 1
    return GaussianScene(
        means, log_scales, quats,
        logit(rng.uniform(0.4, 0.95, n)).astype(np.float32),
        rgb_to_sh_dc(rng.uniform(0.1, 0.9, (n, 3))),
        (rng.normal(0, 0.1, (n, k, 3))).astype(np.float32),
    )
