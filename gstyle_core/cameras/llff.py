"""LLFF ``poses_bounds.npy``: [N,17] = a 3x5 matrix per image (row-major) + near/far bounds.

The 3x5 matrix is camera-to-world: its first three columns are the camera's down, right and
backwards axes in world coordinates, the 4th the camera centre, the 5th [H, W, focal] of the
full-resolution images. LLFF's imgs2poses wrote it from COLMAP poses by permuting the OpenCV axes
(x right, y down, z forward) to (down, right, -forward) and nothing else, so the world is COLMAP's
and stays consistent with ``sparse/0/points3D``. No recentring or rescaling is applied here.
Poses follow the images sorted by file name. The principal point is the image centre.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gstyle_core.cameras.arrays import load_npy
from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import CameraFormatError


def read_poses_bounds(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Load and check ``poses_bounds.npy``: returns (poses [N,3,5], bounds [N,2]) as float64."""
    arr = load_npy(path)
    if arr.ndim != 2 or arr.shape[1] != 17 or arr.shape[0] == 0 or arr.dtype.kind not in "fiu":
        raise CameraFormatError(f"{path.name} must be a numeric [N,17] array, got {arr.dtype} {arr.shape}")
    arr = arr.astype(np.float64)
    if not np.all(np.isfinite(arr)):
        raise CameraFormatError(f"{path.name} contains non-finite values")
    poses = arr[:, :15].reshape(-1, 3, 5)
    hwf = poses[:, :, 4]
    if np.any(hwf <= 0):
        raise CameraFormatError(f"{path.name}: height, width and focal must be positive")
    return poses, arr[:, 15:17]


def llff_pose_to_world_to_cam(pose: np.ndarray) -> np.ndarray:
    """OpenCV world-to-camera 4x4 from one LLFF 3x5 (or 3x4) [down, right, back, centre] matrix."""
    down, right, back, centre = (pose[:, i] for i in range(4))
    rot_c2w = np.stack([right, down, -back], axis=1)  # columns: camera x, y, z in world
    w2c = np.eye(4)
    w2c[:3, :3] = rot_c2w.T
    w2c[:3, 3] = -rot_c2w.T @ centre
    return w2c


def llff_cameras(poses: np.ndarray, names: list[str] | None = None,
                 image_paths: list[Path] | None = None) -> list[Camera]:
    """Cameras at the full resolution stated in the poses' hwf column (principal point at the centre)."""
    cams = []
    for i, pose in enumerate(poses):
        height, width, focal = pose[:, 4]
        w, h = int(round(width)), int(round(height))
        path = image_paths[i] if image_paths else None
        name = names[i] if names else (path.stem if path else f"{i:03d}")
        cams.append(Camera(w, h, float(focal), float(focal), w / 2, h / 2,
                           llff_pose_to_world_to_cam(pose), name, path))
    return cams
