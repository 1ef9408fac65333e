"""The scene's up axis estimated from its cameras (``gstyle_core.cameras.up``)."""

import math

import numpy as np

from gstyle_core.cameras.camera import Camera
from gstyle_core.cameras.generate import generate_cameras, look_at
from gstyle_core.cameras.up import DEFAULT_UP, estimate_up


def angle_deg(a, b) -> float:
    return math.degrees(math.acos(float(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


def tilted_up(seed: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=3)
    return v / np.linalg.norm(v)


def test_a_ring_looking_down_gives_the_ring_axis_not_a_camera_up():
    up = tilted_up(1)
    cams = generate_cameras(np.random.default_rng(0).normal(size=(500, 3)), kind="orbit", count=12, up=up).cameras
    assert angle_deg(-cams[0].cam_to_world[:3, 1], up) > 15  # each camera looks down 20 degrees
    assert angle_deg(estimate_up(cams), up) < 0.01


def test_a_partial_arc_and_a_forward_capture_give_the_cameras_up():
    up = tilted_up(2)
    pts = np.random.default_rng(0).normal(size=(500, 3))
    arc = generate_cameras(pts, kind="arc", count=7, up=up).cameras  # centres on an arc 10 degrees up
    assert angle_deg(estimate_up(arc), up) < 2.0
    # forward-facing: upright cameras on a plane facing the scene (its normal is the view axis, not up)
    right = np.cross(up, [0.3, 0.1, 1.0])
    right /= np.linalg.norm(right)
    fwd = np.cross(right, up)
    cams = [Camera(64, 48, 50, 50, 32, 24, look_at(i * 0.3 * right + j * 0.2 * up, 5 * fwd, up))
            for i in range(-2, 3) for j in range(-1, 2)]
    assert angle_deg(estimate_up(cams), up) < 0.5


def test_one_camera_and_no_camera():
    up = tilted_up(3)
    cam = Camera(64, 48, 50, 50, 32, 24, look_at(np.zeros(3), np.cross(up, [1.0, 0, 0]), up))
    assert angle_deg(estimate_up([cam]), up) < 1e-6
    assert np.allclose(estimate_up([]), DEFAULT_UP)
    assert np.isclose(np.linalg.norm(estimate_up([cam])), 1.0)
