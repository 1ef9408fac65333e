"""Cameras for scenes that come without any (bare .ply / .splat): an orbit or a forward-facing arc.

How the scene is framed:
- centre: per-axis median of the finite Gaussian means (floaters do not move it);
- radius: half the diagonal of the 5th–95th percentile box of the means (floaters do not grow it);
  a point-like cloud (one point, all points equal) gets 1 % of max(1, |centre|) so nothing degenerates;
- distance: the sphere of that radius just fits the field of view of the smaller image side, plus 10 %.
Up axis: by default world -y, the COLMAP / 3DGS convention (their worlds come from OpenCV cameras, whose
y points down, and the first photo is usually held upright). ``up="pca"`` instead takes the axis of least
variance of the central points (right for ground-like scenes, whose extent is mostly horizontal) when
that variance is under a quarter of the middle one (else it falls back to -y). Its sign puts the long
tail of the heights upwards (objects stand on the ground, e.g. +z for gsplat's garden, skewness 1.3);
with a skewness under 0.2 it is signed to agree with -y;
any "+x"/"-x"/…/"-z" string or an explicit 3-vector overrides both.
"""

from __future__ import annotations

import math

import numpy as np

from gstyle_core.cameras.camera import Camera
from gstyle_core.cameras.cameraset import CameraSet

ORBIT_ELEVATION_DEG = 20.0
ARC_ELEVATION_DEG = 10.0
ARC_HALF_SPAN_DEG = 25.0
FRAMING_MARGIN = 1.1
FLATNESS_RATIO = 0.25  # "pca" trusts the least-variance axis only below this fraction of the middle variance
MIN_UP_SKEWNESS = 0.2  # "pca" signs the axis by the skewness of the heights when it is at least this large
_AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0),
         "+z": (0, 0, 1), "-z": (0, 0, -1)}


def generate_cameras(means: np.ndarray, *, kind: str = "auto", count: int = 24, width: int = 640,
                     height: int = 480, fov_deg: float = 50.0, up: str | np.ndarray = "-y",
                     centre: np.ndarray | None = None, radius: float | None = None) -> CameraSet:
    """Cameras looking at the central mass of ``means`` [N,3].

    ``kind``: "orbit" (a full circle ``ORBIT_ELEVATION_DEG`` above the horizon, kind "360"), "arc"
    (±``ARC_HALF_SPAN_DEG`` around the +z side, i.e. looking along world +z like COLMAP's first camera,
    kind "forward") or "auto" (= "orbit": without cameras nothing tells which side is the front).
    ``fov_deg`` is the field of view across the smaller image side. See the module docstring for ``up``.
    Empty or all-non-finite ``means`` are framed as a point at the origin. ``centre`` and ``radius`` given frame
    that sphere instead (the input's, for a stylized result: ``cameras.recorded``). The set's ``generated`` holds
    every parameter that makes the same cameras again (``up`` as the vector it resolved to).
    """
    if kind not in ("auto", "orbit", "arc"):
        raise ValueError(f"generate_cameras: kind must be 'auto', 'orbit' or 'arc', got {kind!r}")
    if count < 1 or width < 1 or height < 1:
        raise ValueError(f"count, width and height must be >= 1, got {count}, {width}, {height}")
    if not 1.0 <= fov_deg <= 170.0:
        raise ValueError(f"generate_cameras: fov_deg must be in [1, 170], got {fov_deg}")
    kind = "orbit" if kind == "auto" else kind
    pts = finite_points(means)
    found_centre, found_radius = robust_centre_radius(pts) if centre is None or radius is None else (None, None)
    centre = found_centre if centre is None else np.asarray(centre, np.float64).reshape(3)
    radius = found_radius if radius is None else float(radius)
    if not (np.isfinite(centre).all() and np.isfinite(radius) and radius > 0):
        raise ValueError(f"generate_cameras: the framed sphere needs a finite centre and a radius > 0, got "
                         f"{centre}, {radius}")
    up_vec = resolve_up(up, pts, centre)
    focal = 0.5 * min(width, height) / math.tan(math.radians(fov_deg) / 2)
    distance = FRAMING_MARGIN * radius / math.sin(math.radians(fov_deg) / 2)
    front = _perpendicular_direction(up_vec)
    side = np.cross(up_vec, front)
    if kind == "orbit":
        azimuths = np.linspace(0.0, 2 * math.pi, count, endpoint=False)
        elevation = math.radians(ORBIT_ELEVATION_DEG)
    else:
        half = math.radians(ARC_HALF_SPAN_DEG)
        azimuths = np.linspace(-half, half, count) if count > 1 else np.zeros(1)
        elevation = math.radians(ARC_ELEVATION_DEG)
    cameras = []
    for i, az in enumerate(azimuths):
        view_dir = math.cos(az) * front + math.sin(az) * side  # horizontal direction the camera looks along
        eye = centre - distance * math.cos(elevation) * view_dir + distance * math.sin(elevation) * up_vec
        cameras.append(Camera(width, height, focal, focal, width / 2, height / 2,
                              look_at(eye, centre, up_vec), name=f"{kind}_{i:03d}"))
    scene_kind = "360" if kind == "orbit" else "forward"
    record = {"kind": kind, "count": count, "width": width, "height": height, "fov_deg": float(fov_deg),
              "up": [float(v) for v in up_vec], "centre": [float(v) for v in centre], "radius": float(radius)}
    return CameraSet(cameras, scene_kind, f"generated-{kind}", generated=record)


def finite_points(means: np.ndarray) -> np.ndarray:
    """Finite rows of ``means`` as float64 [N,3]; raises ValueError when the shape is not [N,3]."""
    arr = np.asarray(means, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        if arr.size == 0:
            return np.zeros((0, 3))
        raise ValueError(f"generate_cameras: means must be [N,3], got shape {arr.shape}")
    return arr[np.all(np.isfinite(arr), axis=1)]


def robust_centre_radius(pts: np.ndarray) -> tuple[np.ndarray, float]:
    """Median centre and half-diagonal of the 5–95 % box, with a floor for point-like clouds."""
    if len(pts) == 0:
        return np.zeros(3), 0.01
    centre = np.median(pts, axis=0)
    lo, hi = np.percentile(pts, [5.0, 95.0], axis=0)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    scale = max(1.0, float(np.abs(centre).max()))
    if not np.isfinite(radius) or radius < 1e-6 * scale:
        radius = 0.01 * scale
    return centre, radius


def resolve_up(up: str | np.ndarray, pts: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Unit world-up vector from an axis name, "pca" or a 3-vector (see module docstring)."""
    default = np.array(_AXES["-y"], np.float64)
    if isinstance(up, str):
        if up == "pca":
            return _least_variance_axis(pts, centre, default)
        if up not in _AXES:
            raise ValueError(f"generate_cameras: up must be one of {sorted(_AXES)}, 'pca' or a 3-vector, "
                             f"got {up!r}")
        return np.array(_AXES[up], np.float64)
    vec = np.asarray(up, np.float64).reshape(-1)
    norm = float(np.linalg.norm(vec)) if vec.shape == (3,) else 0.0
    if not np.isfinite(norm) or norm < 1e-12:
        raise ValueError(f"generate_cameras: up vector must be a finite non-zero 3-vector, got {up!r}")
    return vec / norm


def _least_variance_axis(pts: np.ndarray, centre: np.ndarray, default: np.ndarray) -> np.ndarray:
    if len(pts) < 3:
        return default
    lo, hi = np.percentile(pts, [5.0, 95.0], axis=0)
    core = pts[np.all((pts >= lo) & (pts <= hi), axis=1)] - centre
    if len(core) < 3:
        return default
    eigvals, eigvecs = np.linalg.eigh(np.cov(core.T))
    if not np.all(np.isfinite(eigvals)) or eigvals[-1] <= 0 or eigvals[0] > FLATNESS_RATIO * eigvals[1]:
        return default  # no clearly flat direction
    axis = eigvecs[:, 0]
    heights = core @ axis
    spread = float(heights.std())
    skewness = float(np.mean(heights**3)) / spread**3 if spread > 0 else 0.0
    if abs(skewness) >= MIN_UP_SKEWNESS:  # things stand on the ground: the long tail points up
        return axis if skewness > 0 else -axis
    return axis if axis @ default >= 0 else -axis


def _perpendicular_direction(up_vec: np.ndarray) -> np.ndarray:
    """World +z made perpendicular to ``up_vec`` (or +x when up is along z): the default viewing side."""
    for candidate in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
        proj = candidate - (candidate @ up_vec) * up_vec
        if np.linalg.norm(proj) > 1e-3:
            return proj / np.linalg.norm(proj)
    raise AssertionError("unreachable: +z and +x cannot both be parallel to up")


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """OpenCV world-to-camera 4x4 of a camera at ``eye`` looking at ``target``, world ``up`` = image up."""
    forward = np.asarray(target, np.float64) - np.asarray(eye, np.float64)
    forward /= np.linalg.norm(forward)
    right = np.cross(-np.asarray(up, np.float64), forward)
    if np.linalg.norm(right) < 1e-9:  # looking straight along up: any right vector will do
        right = np.cross(forward, _perpendicular_direction(forward))
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rot = np.stack([right, down, forward])  # rows: camera axes in world coordinates
    w2c = np.eye(4)
    w2c[:3, :3] = rot
    w2c[:3, 3] = -rot @ np.asarray(eye, np.float64)
    return w2c
