"""Camera-control maths (no GL)."""

import math

import numpy as np
import pytest

from app.camera_control import CameraControl, axis_rotation, look_rotation
from gstyle_core.cameras.camera import Camera


def project(cam: Camera, point) -> np.ndarray:
    p = cam.world_to_cam @ np.append(point, 1.0)
    return np.array([cam.fx * p[0] / p[2] + cam.cx, cam.fy * p[1] / p[2] + cam.cy, p[2]])


def test_rotations_are_orthonormal():
    r = axis_rotation([1.0, 2.0, 3.0], 0.7)
    assert np.allclose(r @ r.T, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)
    look = look_rotation([0.0, 0.0, 1.0], [0.0, -1.0, 0.0])
    assert np.allclose(look, np.eye(3))  # OpenCV: looking along +z with -y up is the identity
    degenerate = look_rotation([0.0, -1.0, 0.0], [0.0, -1.0, 0.0])
    assert np.allclose(degenerate.T @ degenerate, np.eye(3))


def test_frame_puts_centre_in_the_middle_and_sphere_inside():
    ctl = CameraControl()
    ctl.frame(np.array([1.0, 2.0, 3.0]), 0.5)
    cam = ctl.camera(400, 300)
    u, v, z = project(cam, [1.0, 2.0, 3.0])
    assert np.allclose([u, v], [200, 150]) and z > 0
    # the sphere's edge along the image-up direction still projects inside the image
    edge = np.array([1.0, 2.0, 3.0]) + 0.5 * ctl.world_up
    assert 0 <= project(cam, edge)[1] <= 300


def test_orbit_keeps_target_distance_and_centre():
    ctl = CameraControl()
    ctl.frame(np.zeros(3), 1.0)
    target, dist = ctl.target.copy(), ctl.pose.distance
    for dx, dy in [(100, 0), (0, 80), (-37, 55)]:
        ctl.orbit(dx, dy)
        assert np.allclose(ctl.target, target) and np.isclose(np.linalg.norm(ctl.pose.eye - target), dist)
        assert np.allclose(project(ctl.camera(64, 48), target)[:2], [32, 24])
    # a horizontal drag rotates about the world up: the eye's height along up is unchanged
    h0 = ctl.pose.eye @ ctl.world_up
    ctl.orbit(250, 0)
    assert np.isclose(ctl.pose.eye @ ctl.world_up, h0)


def test_orbit_never_flips_over_the_pole():
    ctl = CameraControl()
    ctl.frame(np.zeros(3), 1.0)
    ctl.orbit(0, 10_000)
    tilt = math.degrees(math.acos(ctl.pose.rotation[:, 2] @ ctl.world_up))
    assert 1.0 < tilt < 179.0
    assert ctl.pose.rotation[:, 1] @ ctl.world_up < 0  # image up still points to world up


def test_zoom_pan_fly_reset_and_version():
    ctl = CameraControl()
    ctl.frame(np.zeros(3), 1.0)
    home_eye, v0 = ctl.pose.eye.copy(), ctl.version
    d0 = ctl.pose.distance
    ctl.zoom(1)
    assert np.isclose(ctl.pose.distance, 0.9 * d0) and np.allclose(ctl.target, 0, atol=1e-12)
    ctl.pan(10, 0, 300)  # scene follows the cursor: the old target moves right by 10 px
    assert np.isclose(project(ctl.camera(400, 300), np.zeros(3))[0], 210)
    eye = ctl.pose.eye.copy()
    ctl.fly(1, 0, 0, 0.5)
    assert np.allclose(ctl.pose.eye - eye, 0.5 * ctl.fly_speed * ctl.pose.rotation[:, 2])
    assert ctl.version > v0
    ctl.reset()
    assert np.allclose(ctl.pose.eye, home_eye)


def test_zoom_toward_the_cursor_keeps_the_point_under_it():
    """The wheel zooms toward the point under the cursor (at the target's depth): it stays at the same pixel and
    comes closer; a cursor at the view's centre zooms toward the target as before."""
    ctl = CameraControl()
    ctl.frame(np.zeros(3), 1.0)
    cam = ctl.camera(400, 300)
    cursor = (320.0, 90.0)
    depth = ctl.pose.distance
    f = cam.fx
    r = ctl.pose.rotation
    point = ctl.pose.eye + depth * ((cursor[0] - 200) / f * r[:, 0] + (cursor[1] - 150) / f * r[:, 1] + r[:, 2])
    ctl.zoom(2, cursor=cursor, size=(400, 300))
    x, y, z = project(ctl.camera(400, 300), point)
    assert np.allclose((x, y), cursor) and np.isclose(z, 0.81 * depth)
    target = ctl.target.copy()
    ctl.zoom(-1, cursor=(200.0, 150.0), size=(400, 300))
    assert np.allclose(ctl.target, target) and np.isclose(ctl.pose.distance, 0.81 * depth / 0.9)


def test_snap_to_scene_camera_reproduces_its_view():
    w2c = np.eye(4)
    w2c[:3, :3] = axis_rotation([0.2, 1.0, 0.1], 0.8)
    w2c[:3, 3] = [0.1, -0.2, 2.5]
    scene_cam = Camera(640, 480, 500.0, 500.0, 320.0, 240.0, w2c)
    ctl = CameraControl()
    ctl.snap_to(scene_cam)
    cam = ctl.camera(640, 480)
    assert np.allclose(cam.world_to_cam, w2c, atol=1e-9)
    assert np.isclose(cam.fy, 500.0)
    assert np.allclose(ctl.world_up, [0.0, -1.0, 0.0])  # the scene's up, not this camera's


def screen_up_angle_deg(ctl: CameraControl, width: int = 640, height: int = 480) -> float:
    """Angle between the image's vertical and the scene's up axis through the target, as drawn."""
    cam = ctl.camera(width, height)
    a, b = project(cam, ctl.target), project(cam, ctl.target + 0.1 * ctl.pose.distance * ctl.world_up)
    return math.degrees(math.atan2(abs(b[0] - a[0]), a[1] - b[1]))


def test_turntable_orbit_keeps_the_scene_up_vertical_after_a_tilted_scene_camera():
    """R then a horizontal drag: the subject must not lean (issue #27, item 1). The home pose is a scene camera
    looking down 20 degrees at the subject; the orbit turns about the scene's up, not that camera's image-up."""
    from gstyle_core.cameras.generate import generate_cameras
    from gstyle_core.cameras.up import estimate_up

    cams = generate_cameras(np.random.default_rng(0).normal(size=(300, 3)), kind="orbit", count=8).cameras
    ctl = CameraControl()
    ctl.snap_to(cams[0], float(np.linalg.norm(cams[0].position)))
    ctl.home = ctl.pose.copy()
    ctl.set_up(estimate_up(cams))
    ctl.reset()
    for dx, dy in [(300, 0), (-120, 0), (0, 60), (200, -30)]:
        ctl.orbit(dx, dy)
        assert screen_up_angle_deg(ctl) < 0.01
        assert abs(ctl.pose.rotation[:, 0] @ ctl.world_up) < 1e-9  # no roll


def test_orbit_levels_a_rolled_scene_camera():
    w2c = np.eye(4)
    w2c[:3, :3] = axis_rotation([0.0, 0.0, 1.0], 0.3).T  # rolled 17 degrees about its view axis
    w2c[:3, 3] = [0.0, 0.0, 3.0]
    ctl = CameraControl()
    ctl.snap_to(Camera(640, 480, 500.0, 500.0, 320.0, 240.0, w2c), 3.0)
    assert screen_up_angle_deg(ctl) > 10
    ctl.orbit(5, 0)
    assert screen_up_angle_deg(ctl) < 0.01


def test_portrait_view_spans_the_fov_across_its_width():
    ctl = CameraControl()
    ctl.frame(np.zeros(3), 1.0)
    narrow = ctl.camera(220, 480)
    assert np.isclose(2 * math.degrees(math.atan(110 / narrow.fx)), ctl.pose.fov_y_deg)
    side = np.cross(ctl.world_up, ctl.pose.rotation[:, 2])  # the sphere's edge across the view
    assert 0 <= project(narrow, side)[0] <= 220 and 0 <= project(narrow, -side)[0] <= 220


@pytest.mark.parametrize("fov", [1.0, 45.0, 500.0])
def test_fov_is_clamped_and_sets_focal(fov):
    ctl = CameraControl()
    ctl.set_fov(fov)
    assert 10.0 <= ctl.pose.fov_y_deg <= 120.0
    cam = ctl.camera(200, 100)
    assert np.isclose(2 * math.degrees(math.atan(50 / cam.fy)), ctl.pose.fov_y_deg)


def test_look_rotation_is_a_proper_rotation_with_image_up_along_up():
    up = np.array([0.3, -1.0, 0.2])
    up /= np.linalg.norm(up)
    r = look_rotation([1.0, 0.5, 2.0], up)
    assert np.isclose(np.linalg.det(r), 1.0)
    assert r[:, 1] @ up < 0 and abs(r[:, 0] @ up) < 1e-12


def test_drag_down_looks_down():
    ctl = CameraControl()
    ctl.frame(np.zeros(3), 1.0)
    before = ctl.pose.rotation[:, 2] @ ctl.world_up
    ctl.orbit(0, 40)
    assert ctl.pose.rotation[:, 2] @ ctl.world_up < before  # forward turned away from up
    assert ctl.pose.eye @ ctl.world_up > 0  # the eye went up over the target
