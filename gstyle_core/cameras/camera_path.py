"""nerfstudio ``camera_path.json`` (written by its viewer and Blender add-on): read it as cameras, write one.

Format: top-level ``render_width``, ``render_height``, ``fps``, ``seconds`` and ``camera_path``, a list of frames
with ``camera_to_world`` (16 floats, a row-major 4x4), ``fov`` (vertical, degrees) and ``aspect``. Its cameras
follow the OpenGL / nerfstudio convention (x right, y up, looking down -z); ours are OpenCV (x right, y down,
looking down +z), so the camera-to-world matrix is multiplied by diag(1, -1, -1, 1) on the right either way.
Intrinsics: fy = (render_height / 2) / tan(fov / 2), square pixels (fx = fy), principal point at the centre
(a frame's ``aspect`` is not used: every frame is render_width x render_height, as nerfstudio renders it).
The path's world frame is taken as the scene's own.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import CameraFormatError

GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])
MAX_SIDE = 1 << 14
MAX_FRAMES = 100_000


@dataclass
class CameraPath:
    """The cameras of a path, one per frame, and its frame rate."""

    cameras: list[Camera]
    fps: float


def read_camera_path(path: str | os.PathLike) -> CameraPath:
    """Read a nerfstudio camera path; a missing file or malformed content raises ``CameraFormatError``."""
    p = Path(path)
    if not p.is_file():
        raise CameraFormatError(f"camera path not found: {p}")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CameraFormatError(f"{p.name}: not a JSON camera path ({exc})") from None
    if not isinstance(data, dict):
        raise CameraFormatError(f"{p.name}: a camera path is a JSON object, got {type(data).__name__}")
    width, height = _size(data, "render_width", p.name), _size(data, "render_height", p.name)
    fps = _number(data, "fps", p.name, default=30.0)
    if not 0 < fps <= 1000:
        raise CameraFormatError(f"{p.name}: fps must be in (0, 1000], got {fps}")
    kind = data.get("camera_type", "perspective")
    if kind != "perspective":
        raise CameraFormatError(f"{p.name}: only perspective camera paths are supported, got {kind!r}")
    frames = data.get("camera_path")
    if not isinstance(frames, list) or not frames:
        raise CameraFormatError(f"{p.name}: camera_path must be a non-empty list of frames")
    if len(frames) > MAX_FRAMES:
        raise CameraFormatError(f"{p.name}: {len(frames):,} frames (at most {MAX_FRAMES:,})")
    cams = [_camera(frame, i, width, height, p.name) for i, frame in enumerate(frames)]
    return CameraPath(cams, fps)


def _number(data: dict, key: str, name: str, default: float | None = None) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise CameraFormatError(f"{name}: {key} must be a number, got {value!r}")
    return float(value)


def _size(data: dict, key: str, name: str) -> int:
    value = _number(data, key, name)
    if value != int(value) or not 1 <= value <= MAX_SIDE:
        raise CameraFormatError(f"{name}: {key} must be a whole number of pixels in [1, {MAX_SIDE}], got {value}")
    return int(value)


def _camera(frame: object, index: int, width: int, height: int, name: str) -> Camera:
    where = f"{name}: camera_path[{index}]"
    if not isinstance(frame, dict):
        raise CameraFormatError(f"{where} is not an object")
    try:
        c2w_gl = np.asarray(frame.get("camera_to_world"), np.float64)
    except (TypeError, ValueError):
        c2w_gl = np.zeros(0)
    if c2w_gl.size != 16 or not np.all(np.isfinite(c2w_gl)):
        raise CameraFormatError(f"{where}: camera_to_world must be 16 finite numbers (a row-major 4x4)")
    c2w = c2w_gl.reshape(4, 4) @ GL_TO_CV
    rot = c2w[:3, :3]
    if abs(np.linalg.det(rot) - 1.0) > 1e-3 or not np.allclose(rot.T @ rot, np.eye(3), atol=1e-3):
        raise CameraFormatError(f"{where}: camera_to_world is not a rotation and a translation")
    fov = _number(frame, "fov", where)
    if not 0 < fov < 180:
        raise CameraFormatError(f"{where}: fov must be in (0, 180) degrees, got {fov}")
    focal = 0.5 * height / math.tan(math.radians(fov) / 2)
    w2c = np.eye(4)
    w2c[:3, :3] = rot.T
    w2c[:3, 3] = -rot.T @ c2w[:3, 3]
    return Camera(width, height, focal, focal, width / 2, height / 2, w2c, f"path_{index:04d}")


def camera_path_dict(cameras: list[Camera], fps: float = 30.0) -> dict:
    """A nerfstudio camera path through ``cameras`` (sized like the first; its vertical fov from fy)."""
    if not cameras:
        raise ValueError("camera_path_dict: no cameras")
    width, height = cameras[0].width, cameras[0].height
    frames = []
    for cam in cameras:
        c2w_gl = np.linalg.inv(cam.world_to_cam) @ GL_TO_CV
        fov = math.degrees(2 * math.atan(0.5 * cam.height / cam.fy))
        frames.append({"camera_to_world": c2w_gl.reshape(-1).tolist(), "fov": fov, "aspect": cam.width / cam.height})
    return {"camera_type": "perspective", "render_width": width, "render_height": height, "fps": fps,
            "seconds": len(cameras) / fps, "camera_path": frames}
