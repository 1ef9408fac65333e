"""COLMAP sparse models (cameras / images / points3D) in text or binary form.

Only the pinhole part of each camera model is kept (focal lengths and principal point); distortion
parameters are ignored with a warning, as the rasterizer is a pure pinhole. Image poses are COLMAP's
world-to-camera (quaternion qw qx qy qz, translation t), which already uses OpenCV axes.
"""

from __future__ import annotations

import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from gstyle_core.errors import CameraFormatError


class CameraDistortionWarning(UserWarning):
    """A camera model has lens distortion that the pinhole rasterizer ignores."""


@dataclass(frozen=True)
class CameraModel:
    """A COLMAP camera model: id, name, parameter count and where f/c sit in the parameters."""

    model_id: int
    name: str
    num_params: int
    single_focal: bool  # params start with f, cx, cy (else fx, fy, cx, cy)

    @property
    def has_distortion(self) -> bool:
        return self.num_params > (3 if self.single_focal else 4)


CAMERA_MODELS = [
    CameraModel(0, "SIMPLE_PINHOLE", 3, True),
    CameraModel(1, "PINHOLE", 4, False),
    CameraModel(2, "SIMPLE_RADIAL", 4, True),
    CameraModel(3, "RADIAL", 5, True),
    CameraModel(4, "OPENCV", 8, False),
    CameraModel(5, "OPENCV_FISHEYE", 8, False),
    CameraModel(6, "FULL_OPENCV", 12, False),
    CameraModel(7, "FOV", 5, False),
    CameraModel(8, "SIMPLE_RADIAL_FISHEYE", 4, True),
    CameraModel(9, "RADIAL_FISHEYE", 5, True),
    CameraModel(10, "THIN_PRISM_FISHEYE", 12, False),
    CameraModel(11, "RAD_TAN_THIN_PRISM_FISHEYE", 16, False),
]
MODELS_BY_ID = {m.model_id: m for m in CAMERA_MODELS}
MODELS_BY_NAME = {m.name: m for m in CAMERA_MODELS}


@dataclass
class ColmapCamera:
    """Pinhole part of one COLMAP camera (intrinsics shared by several images)."""

    camera_id: int
    model: CameraModel
    width: int
    height: int
    params: np.ndarray  # all model parameters, float64

    @property
    def fx(self) -> float:
        return float(self.params[0])

    @property
    def fy(self) -> float:
        return float(self.params[0] if self.model.single_focal else self.params[1])

    @property
    def cx(self) -> float:
        return float(self.params[1] if self.model.single_focal else self.params[2])

    @property
    def cy(self) -> float:
        return float(self.params[2] if self.model.single_focal else self.params[3])


@dataclass
class ColmapImage:
    """One registered image: world-to-camera pose and the camera it was taken with."""

    image_id: int
    qvec: np.ndarray  # [4] w, x, y, z
    tvec: np.ndarray  # [3]
    camera_id: int
    name: str

    def world_to_cam(self) -> np.ndarray:
        """4x4 world-to-camera matrix (OpenCV axes)."""
        mat = np.eye(4)
        mat[:3, :3] = quat_to_rotmat(self.qvec)
        mat[:3, 3] = self.tvec
        return mat


def quat_to_rotmat(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (not necessarily unit) quaternion w, x, y, z."""
    norm = float(np.linalg.norm(q))
    if not np.isfinite(norm) or norm < 1e-12:
        raise CameraFormatError(f"invalid image rotation quaternion {list(np.round(q, 6))}")
    w, x, y, z = np.asarray(q, np.float64) / norm
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def find_model_dir(path: Path) -> Path | None:
    """Folder holding cameras.{bin,txt}: ``path``, ``path/0``, ``path/sparse/0`` or ``path/sparse``."""
    for candidate in (path, path / "0", path / "sparse" / "0", path / "sparse"):
        if (candidate / "cameras.bin").is_file() or (candidate / "cameras.txt").is_file():
            return candidate
    return None


def model_file(model_dir: Path, stem: str) -> Path | None:
    """``stem.bin`` if present, else ``stem.txt``, else None."""
    for ext in (".bin", ".txt"):
        if (model_dir / f"{stem}{ext}").is_file():
            return model_dir / f"{stem}{ext}"
    return None


def read_cameras(path: Path) -> dict[int, ColmapCamera]:
    """Read cameras.bin or cameras.txt; warn once per distorted model."""
    cams = _guard(path, _read_cameras_bin if path.suffix == ".bin" else _read_cameras_txt)
    for model_name in sorted({c.model.name for c in cams.values() if c.model.has_distortion}):
        warnings.warn(f"COLMAP camera model {model_name}: distortion ignored (pinhole part used)",
                      CameraDistortionWarning, stacklevel=2)
    return cams


def read_images(path: Path) -> list[ColmapImage]:
    """Read images.bin or images.txt (2D observations are skipped), sorted by image name."""
    images = _guard(path, _read_images_bin if path.suffix == ".bin" else _read_images_txt)
    return sorted(images, key=lambda im: im.name)


def read_points3d(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read points3D.bin or points3D.txt as (xyz [M,3] float32, rgb [M,3] float32 in [0,1])."""
    return _guard(path, _read_points_bin if path.suffix == ".bin" else _read_points_txt)


def _guard(path: Path, reader):
    """Run a reader, turning truncation and parse errors into one-line CameraFormatErrors."""
    try:
        if path.suffix == ".bin":
            with open(path, "rb") as fh:
                return reader(fh)
        with open(path, encoding="utf-8", errors="replace") as fh:
            return reader(fh)
    except CameraFormatError as exc:
        raise CameraFormatError(f"{path.name}: {exc}") from None
    except (struct.error, ValueError, IndexError, UnicodeDecodeError, OverflowError, MemoryError) as exc:
        raise CameraFormatError(f"{path.name}: malformed COLMAP file ({exc})") from None
    except OSError as exc:
        raise CameraFormatError(f"cannot read {path}: {exc.strerror or exc}") from None


def _read_exact(fh: BinaryIO, fmt: str) -> tuple:
    size = struct.calcsize(fmt)
    data = fh.read(size)
    if len(data) != size:
        raise CameraFormatError("file is truncated")
    return struct.unpack(fmt, data)


def _skip(fh: BinaryIO, size: int) -> None:
    """Seek ``size`` bytes forward; the size is checked against the file first (never read into memory)."""
    here = fh.tell()
    end = fh.seek(0, 2)
    if size > end - here:
        raise CameraFormatError("file is truncated")
    fh.seek(here + size)


def _read_count(fh: BinaryIO) -> int:
    (count,) = _read_exact(fh, "<Q")
    if count > 1 << 32:
        raise CameraFormatError(f"implausible element count {count}")
    return count


def _make_camera(camera_id: int, model: CameraModel, width: int, height: int, params) -> ColmapCamera:
    params = np.asarray(params, np.float64)
    if width < 1 or height < 1:
        raise CameraFormatError(f"camera {camera_id} has size {width}x{height}")
    cam = ColmapCamera(camera_id, model, int(width), int(height), params)
    if not all(np.isfinite(v) for v in (cam.fx, cam.fy, cam.cx, cam.cy)) or cam.fx <= 0 or cam.fy <= 0:
        raise CameraFormatError(f"camera {camera_id} has invalid intrinsics {params[:4].tolist()}")
    return cam


def _read_cameras_bin(fh: BinaryIO) -> dict[int, ColmapCamera]:
    cams = {}
    for _ in range(_read_count(fh)):
        camera_id, model_id, width, height = _read_exact(fh, "<iiQQ")
        model = MODELS_BY_ID.get(model_id)
        if model is None:
            raise CameraFormatError(f"unknown camera model id {model_id}")
        params = _read_exact(fh, f"<{model.num_params}d")
        cams[camera_id] = _make_camera(camera_id, model, width, height, params)
    return cams


def _read_cameras_txt(fh) -> dict[int, ColmapCamera]:
    cams = {}
    for line in fh:
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        elems = line.split()
        model = MODELS_BY_NAME.get(elems[1]) if len(elems) > 1 else None
        if model is None:
            raise CameraFormatError(f"unknown camera model in line {line[:60]!r}")
        if len(elems) != 4 + model.num_params:
            raise CameraFormatError(f"{model.name} needs {model.num_params} parameters: {line[:60]!r}")
        camera_id = int(elems[0])
        cams[camera_id] = _make_camera(camera_id, model, int(elems[2]), int(elems[3]),
                                       [float(v) for v in elems[4:]])
    return cams


def _read_images_bin(fh: BinaryIO) -> list[ColmapImage]:
    images = []
    for _ in range(_read_count(fh)):
        image_id, qw, qx, qy, qz, tx, ty, tz, camera_id = _read_exact(fh, "<i7di")
        name = bytearray()
        while True:
            ch = fh.read(1)
            if not ch:
                raise CameraFormatError("file is truncated")
            if ch == b"\x00":
                break
            name += ch
        (num_points2d,) = _read_exact(fh, "<Q")
        _skip(fh, 24 * num_points2d)
        images.append(_make_image(image_id, [qw, qx, qy, qz], [tx, ty, tz], camera_id,
                                  name.decode("utf-8", errors="replace")))
    return images


def _read_images_txt(fh) -> list[ColmapImage]:
    images = []
    lines = iter(fh)
    for line in lines:
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        elems = line.split(maxsplit=9)
        if len(elems) < 10:
            raise CameraFormatError(f"image line needs 10 fields: {line[:60]!r}")
        next(lines, "")  # the POINTS2D line that follows every image line (may be empty)
        images.append(_make_image(int(elems[0]), [float(v) for v in elems[1:5]],
                                  [float(v) for v in elems[5:8]], int(elems[8]), elems[9].strip()))
    return images


def _make_image(image_id: int, qvec, tvec, camera_id: int, name: str) -> ColmapImage:
    q, t = np.asarray(qvec, np.float64), np.asarray(tvec, np.float64)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(t))):
        raise CameraFormatError(f"image {name or image_id!r} has a non-finite pose")
    return ColmapImage(image_id, q, t, camera_id, name)


_POINT_STRUCT = struct.Struct("<Q3d3BdQ")  # id, xyz, rgb, error, track length (then 2 int32 per track entry)


def _read_points_bin(fh: BinaryIO) -> tuple[np.ndarray, np.ndarray]:
    data = fh.read()
    if len(data) < 8:
        raise CameraFormatError("file is truncated")
    (count,) = struct.unpack_from("<Q", data, 0)
    if count * _POINT_STRUCT.size > len(data):
        raise CameraFormatError(f"file is truncated ({count} points announced)")
    xyz = np.empty((count, 3), np.float64)
    rgb = np.empty((count, 3), np.uint8)
    offset, size, record = 8, len(data), _POINT_STRUCT
    for i in range(count):
        if offset + record.size > size:
            raise CameraFormatError("file is truncated")
        _, x, y, z, r, g, b, _, track_length = record.unpack_from(data, offset)
        xyz[i] = (x, y, z)
        rgb[i] = (r, g, b)
        offset += record.size + 8 * track_length
    if offset > size:
        raise CameraFormatError("file is truncated")
    return _finish_points(xyz, rgb)


def _read_points_txt(fh) -> tuple[np.ndarray, np.ndarray]:
    xyz, rgb = [], []
    for line in fh:
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        elems = line.split()
        if len(elems) < 8:
            raise CameraFormatError(f"point line needs at least 8 fields: {line[:60]!r}")
        xyz.append([float(v) for v in elems[1:4]])
        rgb.append([int(v) for v in elems[4:7]])
    return _finish_points(np.asarray(xyz, np.float64).reshape(-1, 3),
                          np.clip(np.asarray(rgb, np.int64).reshape(-1, 3), 0, 255))


def _finish_points(xyz: np.ndarray, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    with np.errstate(over="ignore"):  # beyond float32 becomes inf and is dropped
        xyz = xyz.astype(np.float32)
    keep = np.all(np.isfinite(xyz), axis=1)
    return xyz[keep], (rgb[keep].astype(np.float32) / 255.0)
