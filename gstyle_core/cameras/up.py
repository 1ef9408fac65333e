"""The scene's up axis, estimated from its cameras (numpy only): what a turntable orbit turns about.

Photographers hold cameras upright, so the mean of the cameras' image-up directions points up even when each
camera looks down at the subject (the tilts of a ring of cameras cancel). When the camera centres lie on a
plane (a ring or a dome cap around the subject), that plane's normal is a sharper estimate; it is used only when
it agrees with the mean up (a forward-facing capture's cameras lie on a plane facing the scene: its normal is the
viewing direction, not up) and is signed to agree with it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .camera import Camera

DEFAULT_UP = (0.0, -1.0, 0.0)  # COLMAP / 3DGS worlds: OpenCV cameras, y down
PLANE_FLATNESS = 0.25  # the centres lie on a plane when the least spread is under this fraction of the middle one
PLANE_AGREEMENT_DEG = 30.0  # the plane's normal is trusted within this angle of the cameras' mean up


def camera_up_vectors(cameras: Sequence[Camera]) -> np.ndarray:
    """[N, 3] world directions of the cameras' image-up (their -y axis, OpenCV), unit length."""
    ups = -np.array([np.asarray(c.cam_to_world, np.float64)[:3, 1] for c in cameras]).reshape(-1, 3)
    norms = np.linalg.norm(ups, axis=1, keepdims=True)
    return ups / np.maximum(norms, 1e-12)


def estimate_up(cameras: Sequence[Camera], default: Sequence[float] = DEFAULT_UP) -> np.ndarray:
    """Unit world-up vector of a scene from its cameras (module docstring); ``default`` without usable cameras."""
    fallback = np.asarray(default, np.float64) / np.linalg.norm(default)
    if not cameras:
        return fallback
    mean_up = camera_up_vectors(cameras).mean(axis=0)
    norm = float(np.linalg.norm(mean_up))
    if not math.isfinite(norm) or norm < 1e-6:
        return fallback
    mean_up /= norm
    normal = _plane_normal(np.array([np.asarray(c.position, np.float64) for c in cameras]))
    if normal is None:
        return mean_up
    normal = normal if normal @ mean_up >= 0 else -normal
    if normal @ mean_up >= math.cos(math.radians(PLANE_AGREEMENT_DEG)):
        return normal
    return mean_up


def _plane_normal(centres: np.ndarray) -> np.ndarray | None:
    """The normal of the plane the points lie on, or None (fewer than 3, collinear, or not flat)."""
    centres = centres[np.all(np.isfinite(centres), axis=1)]
    if len(centres) < 3:
        return None
    _, spread, axes = np.linalg.svd(centres - centres.mean(axis=0), full_matrices=False)
    if spread[1] <= 1e-9 * max(spread[0], 1e-12) or spread[2] > PLANE_FLATNESS * spread[1]:
        return None
    return axes[2] / np.linalg.norm(axes[2])
