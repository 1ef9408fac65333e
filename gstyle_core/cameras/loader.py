"""``load_cameras``: one entry point for every supported camera source."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from gstyle_core.cameras import colmap
from gstyle_core.cameras.camera import Camera
from gstyle_core.cameras.cameraset import CameraSet
from gstyle_core.cameras.classify import classify_scene_kind
from gstyle_core.cameras.gs_json import read_cameras_json
from gstyle_core.cameras.gsplat_npz import read_gsplat_npz
from gstyle_core.cameras.image_folders import (
    choose_image_dir,
    fit_cameras_to_images,
    list_images,
    scale_cameras,
)
from gstyle_core.cameras.llff import llff_cameras, read_poses_bounds
from gstyle_core.errors import CameraFormatError

MAX_IMAGE_SIDE = 1 << 16
ROTATION_TOLERANCE = 1e-3
_COLMAP_FILES = {f"{stem}{ext}" for stem in ("cameras", "images", "points3D") for ext in (".bin", ".txt")}


def load_cameras(path: str | os.PathLike, *, image_dir: str | os.PathLike | None = None,
                 downscale: int | None = None) -> CameraSet:
    """Read cameras from a 3DGS ``cameras.json``, a COLMAP model, an LLFF scene or a gsplat ``.npz``.

    ``path`` may be the file itself, a COLMAP model folder (``sparse/0``, ``sparse`` or the scene folder
    above it) or a scene folder. In a folder a COLMAP model with images wins, then ``poses_bounds.npy``
    (with ``sparse/0/points3D`` as sparse points if present), then ``cameras.json``.
    ``image_dir`` / ``downscale`` choose the ground-truth image folder (see ``choose_image_dir``);
    intrinsics are rescaled to the size of the images found there. The world frame is kept as stored.
    Missing or malformed input raises ``CameraFormatError``.
    """
    p = Path(path)
    if not p.exists():
        raise CameraFormatError(f"camera source not found: {p}")
    if p.is_file():
        name = p.name
        if p.suffix.lower() == ".json":
            return _from_json(p, image_dir, downscale)
        if p.suffix.lower() == ".npz":
            return _from_npz(p, downscale)
        if name == "poses_bounds.npy":
            return _from_llff(p.parent, image_dir, downscale)
        if name in _COLMAP_FILES:
            return load_cameras(p.parent, image_dir=image_dir, downscale=downscale)
        raise CameraFormatError(f"unknown camera file {name} (expected cameras.json, poses_bounds.npy, "
                                "COLMAP cameras/images/points3D or a gsplat .npz)")
    model_dir = colmap.find_model_dir(p)
    scene_dir = _scene_dir_of(model_dir) if model_dir else p
    if model_dir and colmap.model_file(model_dir, "images"):
        return _from_colmap(model_dir, scene_dir, image_dir, downscale)
    if (scene_dir / "poses_bounds.npy").is_file():
        return _from_llff(scene_dir, image_dir, downscale)
    if (p / "cameras.json").is_file():
        return _from_json(p / "cameras.json", image_dir, downscale)
    if model_dir:
        raise CameraFormatError(f"COLMAP model {model_dir} has no images.bin/images.txt and no "
                                "poses_bounds.npy beside it")
    raise CameraFormatError(f"no cameras in {p} (expected cameras.json, poses_bounds.npy, a COLMAP sparse "
                            "model or a gsplat .npz)")


def _scene_dir_of(model_dir: Path) -> Path:
    """``X`` for ``X/sparse/0`` or ``X/sparse``; the parent folder otherwise."""
    if model_dir.parent.name == "sparse":
        return model_dir.parent.parent
    return model_dir.parent


def check_camera(cam: Camera, where: str) -> None:
    """``CameraFormatError`` unless ``cam`` is usable: a sane image size, positive finite focal lengths,
    a finite principal point and a rigid world-to-camera pose (rotation within ``ROTATION_TOLERANCE``)."""
    if not (1 <= cam.width <= MAX_IMAGE_SIDE and 1 <= cam.height <= MAX_IMAGE_SIDE):
        raise CameraFormatError(f"{where}: image size {cam.width}x{cam.height} is outside 1..{MAX_IMAGE_SIDE}")
    if not (np.isfinite([cam.fx, cam.fy, cam.cx, cam.cy]).all() and cam.fx > 0 and cam.fy > 0):
        raise CameraFormatError(f"{where}: invalid intrinsics fx={cam.fx:.6g} fy={cam.fy:.6g} "
                                f"cx={cam.cx:.6g} cy={cam.cy:.6g}")
    pose = np.asarray(cam.world_to_cam, np.float64)
    if pose.shape != (4, 4) or not np.isfinite(pose).all():
        raise CameraFormatError(f"{where}: the pose is not a finite 4x4 matrix")
    rot = pose[:3, :3]
    rigid = (np.allclose(pose[3], [0, 0, 0, 1]) and np.linalg.det(rot) > 0
             and np.allclose(rot @ rot.T, np.eye(3), atol=ROTATION_TOLERANCE))
    if not rigid:
        raise CameraFormatError(f"{where}: the pose is not a rotation plus a translation")


def _finish(cams: list[Camera], source: Path, points=None, colors=None, near=None, far=None,
            extra_scale: float = 1.0) -> CameraSet:
    label = source.name if source.is_file() else str(source)
    for i, cam in enumerate(cams):
        check_camera(cam, f"{label} camera {cam.name or i!r}")
    cams = scale_cameras(fit_cameras_to_images(cams), extra_scale)
    return CameraSet(cams, classify_scene_kind(cams, points), str(source), points, colors, near, far)


def _from_colmap(model_dir: Path, scene_dir: Path, image_dir, downscale) -> CameraSet:
    intrinsics = colmap.read_cameras(colmap.model_file(model_dir, "cameras"))
    images = colmap.read_images(colmap.model_file(model_dir, "images"))
    if not images:
        raise CameraFormatError(f"COLMAP model {model_dir} has no registered images")
    folder, extra_scale = choose_image_dir(scene_dir, image_dir, downscale)
    cams = []
    for im in images:
        cam = intrinsics.get(im.camera_id)
        if cam is None:
            raise CameraFormatError(f"COLMAP image {im.name!r} refers to missing camera {im.camera_id}")
        image_path = folder / im.name if folder is not None else None
        cams.append(Camera(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy, im.world_to_cam(),
                           Path(im.name).stem, image_path if image_path and image_path.is_file() else None))
    if image_dir is not None and all(c.image_path is None for c in cams):
        raise CameraFormatError(f"none of the {len(cams)} COLMAP images is in {folder}")
    points, colors = _colmap_points(model_dir)
    return _finish(cams, model_dir, points, colors, extra_scale=extra_scale)


def _colmap_points(model_dir: Path | None) -> tuple[np.ndarray | None, np.ndarray | None]:
    points_file = colmap.model_file(model_dir, "points3D") if model_dir else None
    if points_file is None:
        return None, None
    points, colors = colmap.read_points3d(points_file)
    return (points, colors) if len(points) else (None, None)


def _from_llff(scene_dir: Path, image_dir, downscale) -> CameraSet:
    poses, bounds = read_poses_bounds(scene_dir / "poses_bounds.npy")
    folder, extra_scale = choose_image_dir(scene_dir, image_dir, downscale)
    paths = None
    if folder is not None:
        paths = list_images(folder)
        if len(paths) != len(poses):
            raise CameraFormatError(f"{folder.name} has {len(paths)} images but poses_bounds.npy has "
                                    f"{len(poses)} poses")
    points, colors = _colmap_points(colmap.find_model_dir(scene_dir))
    return _finish(llff_cameras(poses, image_paths=paths), scene_dir, points, colors,
                   float(bounds.min()), float(bounds.max()), extra_scale)


def _from_json(path: Path, image_dir, downscale) -> CameraSet:
    cams = read_cameras_json(path)
    folder, extra_scale = choose_image_dir(path.parent, image_dir, downscale)
    if folder is not None:
        by_stem = {p.stem: p for p in list_images(folder)}
        by_name = {p.name: p for p in by_stem.values()}
        for cam in cams:
            cam.image_path = by_name.get(cam.name) or by_stem.get(Path(cam.name).stem)
        if image_dir is not None and all(c.image_path is None for c in cams):
            raise CameraFormatError(f"none of the {len(cams)} images named in {path.name} is in {folder}")
    return _finish(cams, path, extra_scale=extra_scale)


def _from_npz(path: Path, downscale) -> CameraSet:
    if downscale is not None and (int(downscale) != downscale or downscale < 1):
        raise CameraFormatError(f"downscale must be a positive integer, got {downscale}")
    cams, points, colors = read_gsplat_npz(path)
    return _finish(cams, path, points, colors, extra_scale=1.0 / downscale if downscale else 1.0)
