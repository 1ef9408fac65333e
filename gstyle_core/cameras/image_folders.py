"""Finding a scene's image folder and fitting camera intrinsics to the images actually on disk."""

from __future__ import annotations

import re
from pathlib import Path

from gstyle_core.cameras.camera import Camera
from gstyle_core.cameras.images import image_size
from gstyle_core.errors import CameraFormatError

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}
_DOWNSCALED = re.compile(r"^images_(\d+)$")


def list_images(folder: Path) -> list[Path]:
    """Image files in ``folder`` (not hidden), sorted by name."""
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith("."))


def choose_image_dir(scene_dir: Path, image_dir: str | Path | None,
                     downscale: int | None) -> tuple[Path | None, float]:
    """Pick the image folder and the extra scale still to apply to the cameras.

    - ``image_dir`` given: that folder (relative paths are taken from ``scene_dir``); it must exist.
    - ``downscale=N``: ``images_N`` if present; else the ``images_M`` with the largest M < N (extra scale
      M/N); else ``images`` (extra scale 1/N); else no folder and extra scale 1/N.
    - neither: ``images`` if present, else the ``images_N`` with the smallest N, else no folder.
    """
    if downscale is not None and (int(downscale) != downscale or downscale < 1):
        raise CameraFormatError(f"downscale must be a positive integer, got {downscale}")
    if image_dir is not None:
        folder = Path(image_dir)
        folder = folder if folder.is_absolute() else scene_dir / folder
        if not folder.is_dir():
            raise CameraFormatError(f"image folder not found: {folder}")
        return folder, 1.0 if downscale is None else 1.0 / downscale
    downscaled = sorted((int(m.group(1)), p) for p in scene_dir.glob("images_*")
                        if p.is_dir() and (m := _DOWNSCALED.match(p.name)) and int(m.group(1)) >= 1)
    if downscale is not None and downscale > 1:
        finer = [(factor, folder) for factor, folder in downscaled if factor <= downscale]
        if finer:
            factor, folder = finer[-1]
            return folder, factor / downscale
        return ((scene_dir / "images") if (scene_dir / "images").is_dir() else None), 1.0 / downscale
    if (scene_dir / "images").is_dir():
        return scene_dir / "images", 1.0
    return (downscaled[0][1] if downscaled else None), 1.0


def fit_to_image_size(cam: Camera, width: int, height: int, image_name: str = "") -> Camera:
    """Rescale intrinsics to a ``width`` x ``height`` image (same aspect within rounding); pose kept."""
    if (width, height) == (cam.width, cam.height):
        return cam
    sx, sy = width / cam.width, height / cam.height
    # downscaled folders round each side separately: allow a pixel of rounding on either side
    tolerance = max(0.01, 1.5 / min(width, height))
    if abs(sx / sy - 1.0) > tolerance:
        raise CameraFormatError(
            f"image {image_name} is {width}x{height} but its camera is {cam.width}x{cam.height} "
            "(other aspect)")
    return Camera(width, height, cam.fx * sx, cam.fy * sy, cam.cx * sx, cam.cy * sy,
                  cam.world_to_cam.copy(), cam.name, cam.image_path)


def fit_cameras_to_images(cameras: list[Camera]) -> list[Camera]:
    """Fit each camera with an image to that image's size (one header read per distinct camera size)."""
    fitted, seen = [], {}
    for cam in cameras:
        if cam.image_path is None:
            fitted.append(cam)
            continue
        key = (cam.width, cam.height, cam.image_path.parent)
        size = seen.get(key)
        if size is None:
            size = seen[key] = image_size(cam.image_path)
        fitted.append(fit_to_image_size(cam, *size, image_name=cam.image_path.name))
    return fitted


def scale_cameras(cameras: list[Camera], factor: float) -> list[Camera]:
    """``Camera.scaled(factor)`` for every camera (no-op for factor 1)."""
    return cameras if factor == 1.0 else [c.scaled(factor) for c in cameras]
