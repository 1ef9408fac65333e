"""Framing a scene in a view, as desktop 3D tools' "frame all" does (numpy only): the robust box of the Gaussian
centres seen whole, with a margin on every side of the image.

The box: per axis, the 0.5th to 99.5th percentile of the finite centres, so that a few floaters do not shrink the
subject to a dot (a bare scene file's generated cameras instead fit a sphere around the 5-95 % box, which lets the
top of the demo's fountain touch the image's edge). The distance: the camera looks at the box's centre along a
given direction, from just far enough that each of the box's eight corners projects at least ``margin`` of the
image's width (height) inside its left and right (top and bottom) edges; the field of view spans the image's
smaller side, as everywhere in the studio and the generated cameras.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .camera import Camera
from .generate import look_at

BOX_PERCENT = 0.5  # the box spans the BOX_PERCENT-th to (100 - BOX_PERCENT)-th percentile of the centres per axis
FRAME_MARGIN = 0.05  # fraction of the image's width (height) left free beside (above and below) the box
MIN_BOX_SIDE = 1e-3  # a flat or point-like box is grown to this fraction of its size scale


def scene_box(means: np.ndarray, percent: float = BOX_PERCENT) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) corners of the robust box of ``means`` [N, 3] (non-finite rows ignored); a unit box at the origin
    when there is none. Sides shorter than ``MIN_BOX_SIDE`` of the largest coordinate (at least 1) are widened."""
    pts = np.asarray(means, np.float64).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        return np.full(3, -0.5), np.full(3, 0.5)
    lo, hi = np.percentile(pts, [percent, 100.0 - percent], axis=0)
    floor = MIN_BOX_SIDE * max(1.0, float(np.abs(np.concatenate([lo, hi])).max()))
    grow = np.maximum(floor - (hi - lo), 0.0) / 2
    return lo - grow, hi + grow


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """[8, 3] corners of the axis-aligned box (lo, hi)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1)
                     for k in (0, 1)])


def focal_for(width: int, height: int, fov_deg: float) -> float:
    """Focal length in pixels for a field of view ``fov_deg`` across the image's smaller side."""
    return 0.5 * min(width, height) / math.tan(math.radians(fov_deg) / 2)


def fit_distance(points: np.ndarray, target: np.ndarray, rotation: np.ndarray, focal: float, width: int,
                 height: int, margin: float = FRAME_MARGIN) -> float:
    """How far from ``target`` a camera looking at it with camera-to-world ``rotation`` (columns: right, down,
    forward) must stand for every one of ``points`` [M, 3] to project at least ``margin`` of the image's width
    (height) inside its edges (principal point in the middle, square pixels of ``focal``)."""
    rel = (np.asarray(points, np.float64).reshape(-1, 3) - np.asarray(target, np.float64)) @ np.asarray(rotation)
    half_w = max(width * (0.5 - margin), 1.0)
    half_h = max(height * (0.5 - margin), 1.0)
    # a point at (a, b, e) about the target is seen at depth d + e: |a| f / (d + e) <= half_w, the same for b
    need = np.maximum(np.abs(rel[:, 0]) * focal / half_w, np.abs(rel[:, 1]) * focal / half_h) - rel[:, 2]
    extent = max(float(np.linalg.norm(rel, axis=1).max()), 1e-6)
    in_front = MIN_BOX_SIDE * extent - float(rel[:, 2].min())  # every point in front of the camera
    return max(float(need.max()), in_front)


def projected_bounds(points: np.ndarray, eye: np.ndarray, rotation: np.ndarray, focal: float, width: int,
                     height: int) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) pixel bounds of ``points`` [M, 3] seen from ``eye`` with camera-to-world ``rotation``
    (row 0 = top of the image; the points must lie in front of the camera)."""
    rel = (np.asarray(points, np.float64).reshape(-1, 3) - np.asarray(eye, np.float64)) @ np.asarray(rotation)
    x = focal * rel[:, 0] / rel[:, 2] + width / 2
    y = focal * rel[:, 1] / rel[:, 2] + height / 2
    return float(x.min()), float(y.min()), float(x.max()), float(y.max())


def frame_cameras(cameras: Sequence[Camera], lo: np.ndarray, hi: np.ndarray, up: np.ndarray,
                  margin: float = FRAME_MARGIN) -> list[Camera]:
    """``cameras`` (each keeps its viewing direction, image size and focal length) turned to look at the centre of
    the box (lo, hi), levelled to ``up``, all at the one distance that frames the whole box with ``margin`` free
    on every side in each of them (a turntable's frames then neither zoom nor touch the edge)."""
    centre = (np.asarray(lo, np.float64) + np.asarray(hi, np.float64)) / 2
    corners = box_corners(lo, hi)
    rotations = []
    for cam in cameras:
        rotations.append(look_at(centre - cam.forward, centre, up)[:3, :3].T)  # camera-to-world, levelled
    distance = max(fit_distance(corners, centre, rot, min(cam.fx, cam.fy), cam.width, cam.height, margin)
                   for cam, rot in zip(cameras, rotations, strict=True)) if cameras else 1.0
    return [replace(cam, world_to_cam=look_at(centre - distance * rot[:, 2], centre, up))
            for cam, rot in zip(cameras, rotations, strict=True)]


def extent_growth(before: np.ndarray, after: np.ndarray) -> dict[str, float]:
    """How much further out the centres ``after`` [M, 3] reach than ``before`` [N, 3] (a stylized result against its
    input), as ratios after / before (1: no growth): ``radius`` of the sphere generated cameras frame
    (``generate.robust_centre_radius``), ``box`` the diagonal of the framing box (``scene_box``), ``max_distance``
    the farthest centre from the input's centre; ``outside_share`` the fraction of ``after`` outside the input's box
    grown by 1 % of its diagonal (0 for none)."""
    from .generate import finite_points, robust_centre_radius

    old, new = finite_points(before), finite_points(after)
    centre, radius = robust_centre_radius(old)
    lo, hi = scene_box(old)
    diag = float(np.linalg.norm(hi - lo))
    new_lo, new_hi = scene_box(new)
    pad = 0.01 * diag
    outside = np.any((new < lo - pad) | (new > hi + pad), axis=1) if len(new) else np.zeros(0, bool)
    reach = float(np.linalg.norm(old - centre, axis=1).max()) if len(old) else 0.0

    def ratio(a: float, b: float) -> float:
        return a / b if b > 0 else 1.0

    return {"radius": ratio(robust_centre_radius(new)[1], radius),
            "box": ratio(float(np.linalg.norm(new_hi - new_lo)), diag),
            "max_distance": ratio(float(np.linalg.norm(new - centre, axis=1).max()) if len(new) else 0.0, reach),
            "outside_share": float(outside.mean()) if len(outside) else 0.0}
