"""gsplat's test-scene ``.npz`` (e.g. ``test_garden.npz``): viewmats, Ks, width, height, means3d, colors.

``viewmats`` [C,4,4] are OpenCV world-to-camera matrices, ``Ks`` [C,3,3] pinhole intrinsics, ``width`` and
``height`` scalars shared by all cameras; ``means3d`` [M,3] and ``colors`` [M,3] (uint8) a point cloud.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gstyle_core.cameras.arrays import load_npz
from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import CameraFormatError


def read_gsplat_npz(path: Path) -> tuple[list[Camera], np.ndarray | None, np.ndarray | None]:
    """Return (cameras, points [M,3] float32 or None, colours [M,3] in [0,1] or None)."""
    arrays = load_npz(path)
    missing = [k for k in ("viewmats", "Ks", "width", "height") if k not in arrays]
    if missing:
        raise CameraFormatError(f"{path.name} lacks {', '.join(missing)} (not a gsplat camera npz)")
    viewmats, ks = _real(arrays, "viewmats", path.name), _real(arrays, "Ks", path.name)
    if viewmats.ndim != 3 or viewmats.shape[1:] != (4, 4) or ks.shape != (len(viewmats), 3, 3) or not len(ks):
        raise CameraFormatError(f"{path.name}: viewmats must be [C,4,4] and Ks [C,3,3] (got "
                                f"{viewmats.shape}, {ks.shape})")
    if arrays["width"].size != 1 or arrays["height"].size != 1:
        raise CameraFormatError(f"{path.name}: width and height must be scalars")
    size = [float(_real(arrays, key, path.name).item()) for key in ("width", "height")]
    if not np.all(np.isfinite(size)) or max(size) > 2**31:
        raise CameraFormatError(f"{path.name}: width and height must be finite numbers, got {size}")
    width, height = (int(v) for v in size)
    if width < 1 or height < 1 or not (np.all(np.isfinite(viewmats)) and np.all(np.isfinite(ks))):
        raise CameraFormatError(f"{path.name}: invalid image size or non-finite cameras")
    if np.any(ks[:, 0, 0] <= 0) or np.any(ks[:, 1, 1] <= 0):
        raise CameraFormatError(f"{path.name}: focal lengths must be positive")
    cams = [Camera(width, height, float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]),
                   v.copy(), f"{i:03d}") for i, (v, k) in enumerate(zip(viewmats, ks, strict=True))]
    points, colors = _points(arrays, path.name)
    return cams, points, colors


def _real(arrays: dict[str, np.ndarray], key: str, name: str) -> np.ndarray:
    """``arrays[key]`` as float64; CameraFormatError unless it holds real numbers."""
    arr = arrays[key]
    if arr.dtype.kind not in "fiub":
        raise CameraFormatError(f"{name}: {key} must hold real numbers, got {arr.dtype}")
    return arr.astype(np.float64)


def _points(arrays: dict[str, np.ndarray], name: str) -> tuple[np.ndarray | None, np.ndarray | None]:
    if "means3d" not in arrays:
        return None, None
    with np.errstate(over="ignore"):  # beyond float32 becomes inf and is dropped below
        points = _real(arrays, "means3d", name).astype(np.float32)
    if points.ndim != 2 or points.shape[1] != 3:
        raise CameraFormatError(f"{name}: means3d must be [M,3], got {points.shape}")
    keep = np.all(np.isfinite(points), axis=1)
    colors = None
    if "colors" in arrays:
        raw = _real(arrays, "colors", name)
        if raw.shape != points.shape:
            raise CameraFormatError(f"{name}: colors must match means3d, got {raw.shape}")
        scale = 255.0 if np.issubdtype(arrays["colors"].dtype, np.integer) else 1.0
        colors = np.clip(np.nan_to_num(raw / scale), 0.0, 1.0).astype(np.float32)[keep]
    return points[keep], colors
