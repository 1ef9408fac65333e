"""The reference 3DGS ``cameras.json``: a list of {id, img_name, width, height, position, rotation, fx, fy}.

``rotation`` is the 3x3 camera-to-world rotation (its columns are the camera's x right / y down /
z forward axes in world coordinates) and ``position`` the camera centre. The format has no principal
point, so it is the image centre when absent; we write ``cx``/``cy`` as extra keys (readers of the
reference format ignore unknown keys) so a round trip keeps off-centre principal points.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from gstyle_core.atomic import atomic_write_text
from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import CameraFormatError


def read_cameras_json(path: Path) -> list[Camera]:
    """Parse a 3DGS cameras.json (entries sorted by ``id`` when all have one)."""
    try:
        entries = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:  # ValueError: bad JSON, bad UTF-8, 5000-digit numbers
        reason = "nested too deeply" if isinstance(exc, RecursionError) else (str(exc).splitlines() or ["?"])[0]
        raise CameraFormatError(f"cannot read {Path(path).name}: {reason}") from None
    if not isinstance(entries, list) or not entries:
        raise CameraFormatError(f"{Path(path).name} must be a non-empty JSON list of cameras")
    if all(isinstance(e, dict) and isinstance(e.get("id"), int) for e in entries):
        entries = sorted(entries, key=lambda e: e["id"])
    return [_camera_from_entry(e, i, Path(path).name) for i, e in enumerate(entries)]


def _camera_from_entry(entry: object, index: int, file_name: str) -> Camera:
    where = f"{file_name} camera {index}"
    if not isinstance(entry, dict):
        raise CameraFormatError(f"{where} is not an object")
    missing = [k for k in ("width", "height", "position", "rotation", "fx", "fy") if k not in entry]
    if missing:
        raise CameraFormatError(f"{where} lacks {', '.join(missing)}")
    try:
        width, height = int(entry["width"]), int(entry["height"])
        fx, fy = float(entry["fx"]), float(entry["fy"])
        cx = float(entry.get("cx", width / 2))
        cy = float(entry.get("cy", height / 2))
        position = np.asarray(entry["position"], np.float64)
        rotation = np.asarray(entry["rotation"], np.float64)
    except (TypeError, ValueError, OverflowError) as exc:  # OverflowError: int(inf) from 1e400
        raise CameraFormatError(f"{where} has a malformed field ({exc})") from None
    if position.shape != (3,) or rotation.shape != (3, 3):
        raise CameraFormatError(f"{where}: position must be 3 numbers and rotation 3x3")
    values = [fx, fy, cx, cy, *position.tolist(), *rotation.ravel().tolist()]
    if width < 1 or height < 1 or not all(math.isfinite(v) for v in values) or fx <= 0 or fy <= 0:
        raise CameraFormatError(f"{where} has invalid size, focal or non-finite pose")
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-3) or np.linalg.det(rotation) < 0:
        raise CameraFormatError(f"{where}: rotation is not a rotation matrix")
    w2c = np.eye(4)
    w2c[:3, :3] = rotation.T
    w2c[:3, 3] = -rotation.T @ position
    name = str(entry.get("img_name", f"{index:05d}"))
    return Camera(width, height, fx, fy, cx, cy, w2c, name)


def save_cameras_json(cameraset, path: str | os.PathLike) -> None:
    """Write cameras (a CameraSet or a list of Camera) as a 3DGS cameras.json, atomically."""
    cams = getattr(cameraset, "cameras", cameraset)
    entries = []
    for i, cam in enumerate(cams):
        c2w = cam.cam_to_world
        name = cam.name or (cam.image_path.stem if cam.image_path else f"{i:05d}")
        entries.append({
            "id": i, "img_name": name, "width": int(cam.width), "height": int(cam.height),
            "position": c2w[:3, 3].tolist(), "rotation": c2w[:3, :3].tolist(),
            "fy": float(cam.fy), "fx": float(cam.fx), "cx": float(cam.cx), "cy": float(cam.cy),
        })
    atomic_write_text(path, json.dumps(entries, indent=1) + "\n")
