"""Forward-facing vs 360° classification of a camera set (it picks G-Style's schedule and weights)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gstyle_core.cameras.camera import Camera

FORWARD_SPREAD_MAX_DEG = 45.0
CENTRE_SPAN_MAX_DEG = 45.0
PARALLEL_AXES_DEG = 5.0


def classify_scene_kind(cameras, points: np.ndarray | None = None) -> str:
    """Return "forward" or "360" for a ``CameraSet`` or a list of ``Camera``.

    Rule: the scene is "forward" when (a) every camera's viewing direction lies within 45° of the
    mean viewing direction, and (b) seen from the scene centre, every camera centre lies within 45°
    of the mean direction towards the cameras (the cameras sit on one side of the scene).
    Otherwise it is "360". The scene centre is the median of the sparse ``points`` when known (taken
    from the CameraSet if not given), else the point nearest to all optical axes in the least-squares
    sense; without points and with near-parallel axes (no such focus) (b) holds trivially.
    Zero or one camera counts as "forward".
    """
    cams: Sequence[Camera] = getattr(cameras, "cameras", cameras)
    if points is None:
        points = getattr(cameras, "points", None)
    if len(cams) < 2:
        return "forward"
    forwards = np.stack([c.forward for c in cams])
    mean_forward = forwards.mean(axis=0)
    if np.linalg.norm(mean_forward) < 1e-6:
        return "360"
    if max_angle_deg(forwards, mean_forward) > FORWARD_SPREAD_MAX_DEG:
        return "360"
    centres = np.stack([c.position for c in cams])
    centre = scene_centre(centres, forwards, points)
    if centre is None:
        return "forward"
    offsets = centres - centre
    dist = np.linalg.norm(offsets, axis=1)
    offsets = offsets[dist > 1e-9 * max(1.0, float(np.abs(centre).max()))]
    if len(offsets) < 2:
        return "forward"
    directions = offsets / np.linalg.norm(offsets, axis=1, keepdims=True)
    mean_dir = directions.mean(axis=0)
    if np.linalg.norm(mean_dir) < 1e-6:
        return "360"
    return "forward" if max_angle_deg(directions, mean_dir) <= CENTRE_SPAN_MAX_DEG else "360"


def max_angle_deg(unit_vectors: np.ndarray, reference: np.ndarray) -> float:
    """Largest angle in degrees between rows of ``unit_vectors`` [N,3] and ``reference`` [3]."""
    ref = reference / np.linalg.norm(reference)
    return float(np.degrees(np.arccos(np.clip(unit_vectors @ ref, -1.0, 1.0))).max())


def scene_centre(centres: np.ndarray, forwards: np.ndarray,
                 points: np.ndarray | None = None) -> np.ndarray | None:
    """Median of finite ``points``; else the least-squares focus of the optical axes.

    Returns None when there are no points and the axes are too close to parallel (within about
    ``PARALLEL_AXES_DEG``) for a focus to exist: the cameras then all look one way from one side.
    """
    if points is not None:
        pts = np.asarray(points, np.float64).reshape(-1, 3)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts):
            return np.median(pts, axis=0)
    a = np.zeros((3, 3))
    b = np.zeros(3)
    for o, f in zip(centres, forwards, strict=True):
        proj = np.eye(3) - np.outer(f, f)
        a += proj
        b += proj @ o
    if np.linalg.eigvalsh(a)[0] < len(centres) * np.sin(np.radians(PARALLEL_AXES_DEG)) ** 2:
        return None
    return np.linalg.solve(a, b)
