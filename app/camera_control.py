"""Viewer camera maths: a turntable orbit around a target, WASD fly, dolly (zoom), pan, reset, snap to a scene
camera, fov.

Pure numpy, no GL. Pose = eye position + camera-to-world rotation (columns: x right, y down, z forward,
the OpenCV axes of ``gstyle_core.cameras.Camera``) + the distance to the orbit target along the view axis.
The orbit is a turntable, as in Blender, SuperSplat or Sketchfab: a horizontal drag turns about the scene's up
axis (``world_up``, estimated from the scene cameras by ``gstyle_core.cameras.up.estimate_up``), a vertical drag
tilts about the view's right axis, and the view is kept level (no roll), so the subject never leans.
The field of view spans the view's smaller side (a tall, narrow view beside the panel sees as much across as a
wide one sees from top to bottom).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gstyle_core.cameras.camera import Camera
from gstyle_core.cameras.framing import FRAME_MARGIN, box_corners, fit_distance, focal_for

MIN_FOV_DEG, MAX_FOV_DEG = 10.0, 120.0
MIN_DISTANCE = 1e-3
POLE_MARGIN_DEG = 2.0  # orbit never tilts closer than this to straight up/down


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` radians about unit ``axis`` (right-handed, Rodrigues)."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def look_rotation(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Camera-to-world rotation looking along ``forward`` with image-up towards ``up`` (OpenCV: y down)."""
    z = np.asarray(forward, np.float64)
    z = z / np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, np.float64))  # right = forward x up (y down = -up)
    if np.linalg.norm(x) < 1e-9:  # looking straight along up: pick any perpendicular right axis
        x = np.cross(z, [1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.cross(z, [0.0, 1.0, 0.0])
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


@dataclass
class Pose:
    """Eye, camera-to-world rotation, orbit distance, vertical field of view."""

    eye: np.ndarray
    rotation: np.ndarray
    distance: float
    fov_y_deg: float

    def copy(self) -> Pose:
        return Pose(self.eye.copy(), self.rotation.copy(), self.distance, self.fov_y_deg)


@dataclass
class CameraControl:
    """Interactive camera state; all inputs are plain numbers so the maths is unit-testable."""

    world_up: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    orbit_speed: float = 0.005  # radians per pixel of drag
    fly_speed: float = 1.0  # world units per second (set from the scene size by ``frame``)
    home: Pose = field(default_factory=lambda: Pose(np.array([0.0, 0.0, -3.0]), np.eye(3), 3.0, 50.0))
    pose: Pose = field(init=False)
    version: int = field(default=0, init=False)  # bumped on every change: a cheap "did the view move?"

    def __post_init__(self) -> None:
        self.world_up = np.asarray(self.world_up, np.float64) / np.linalg.norm(self.world_up)
        self.pose = self.home.copy()

    # ----------------------------------------------------------------- derived
    @property
    def target(self) -> np.ndarray:
        """Orbit centre: ``distance`` in front of the eye."""
        return self.pose.eye + self.pose.distance * self.pose.rotation[:, 2]

    def camera(self, width: int, height: int) -> Camera:
        """A pinhole Camera for an image of this size (square pixels, centred principal point; the field of view
        spans the smaller side)."""
        f = 0.5 * min(width, height) / math.tan(math.radians(self.pose.fov_y_deg) / 2)
        c2w = np.eye(4)
        c2w[:3, :3], c2w[:3, 3] = self.pose.rotation, self.pose.eye
        return Camera(int(width), int(height), f, f, width / 2, height / 2, np.linalg.inv(c2w), "viewer")

    # ----------------------------------------------------------------- setting the pose
    def frame(self, centre: np.ndarray, radius: float, direction: np.ndarray | None = None,
              fov_y_deg: float = 50.0) -> None:
        """Look at a sphere (centre, radius) from ``direction`` (default: horizontal) and make it the home pose."""
        radius = max(float(radius), 1e-6)
        if direction is None:
            direction = look_rotation(np.cross(self.world_up, [1.0, 0.0, 0.0]) if abs(self.world_up[0]) < 0.9
                                      else np.cross(self.world_up, [0.0, 0.0, 1.0]), self.world_up)[:, 2]
        forward = np.asarray(direction, np.float64) / np.linalg.norm(direction)
        distance = 1.1 * radius / math.sin(math.radians(fov_y_deg) / 2)
        eye = np.asarray(centre, np.float64) - distance * forward
        self.home = Pose(eye, look_rotation(forward, self.world_up), distance, fov_y_deg)
        self.fly_speed = radius
        self.reset()

    def frame_box(self, lo: np.ndarray, hi: np.ndarray, width: int, height: int,
                  direction: np.ndarray | None = None, set_home: bool = True, margin: float = FRAME_MARGIN) -> None:
        """Frame all: look at the centre of the box (lo, hi) along ``direction`` (default: the current view's),
        levelled, from just far enough to see the whole box in a ``width`` x ``height`` view with ``margin`` of its
        size free on every side (``gstyle_core.cameras.framing``). ``set_home``: R comes back to this pose."""
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        forward = self.pose.rotation[:, 2] if direction is None else np.asarray(direction, np.float64)
        rotation = look_rotation(forward / np.linalg.norm(forward), self.world_up)
        centre = (lo + hi) / 2
        fov = self.pose.fov_y_deg
        distance = fit_distance(box_corners(lo, hi), centre, rotation, focal_for(width, height, fov), width, height,
                                margin)
        self.pose = Pose(centre - distance * rotation[:, 2], rotation, distance, fov)
        if set_home:
            self.home = self.pose.copy()
        self.fly_speed = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        self.version += 1

    def set_up(self, up: np.ndarray) -> None:
        """The axis the orbit turns about (the scene's up); the home pose and the view are levelled to it."""
        self.world_up = np.asarray(up, np.float64) / np.linalg.norm(up)
        self.home.rotation = look_rotation(self.home.rotation[:, 2], self.world_up)
        self.level()

    def level(self) -> None:
        """Remove the view's roll about its axis (image-up towards ``world_up``), the target kept."""
        target = self.target
        self.pose.rotation = look_rotation(self.pose.rotation[:, 2], self.world_up)
        self.pose.eye = target - self.pose.distance * self.pose.rotation[:, 2]
        self.version += 1

    def reset(self) -> None:
        """Back to the home pose."""
        self.pose = self.home.copy()
        self.version += 1

    def snap_to(self, camera: Camera, target_distance: float | None = None) -> None:
        """Take a scene camera's pose (its roll too, until the next orbit levels it) and vertical field of view."""
        c2w = camera.cam_to_world
        rotation = c2w[:3, :3] / np.linalg.norm(c2w[:3, :3], axis=0)
        fov = math.degrees(2 * math.atan(0.5 * camera.height / camera.fy))
        distance = self.pose.distance if target_distance is None else float(target_distance)
        self.pose = Pose(c2w[:3, 3].copy(), rotation, max(distance, MIN_DISTANCE),
                         float(np.clip(fov, MIN_FOV_DEG, MAX_FOV_DEG)))
        self.version += 1

    def set_fov(self, fov_y_deg: float) -> None:
        """Vertical field of view in degrees, clamped to [10, 120]."""
        self.pose.fov_y_deg = float(np.clip(fov_y_deg, MIN_FOV_DEG, MAX_FOV_DEG))
        self.version += 1

    # ----------------------------------------------------------------- interaction
    def orbit(self, dx_pixels: float, dy_pixels: float) -> None:
        """Drag: turntable orbit around the target (dx about the world up, dy about the view's right axis), level."""
        target = self.target
        yaw = axis_rotation(self.world_up, -dx_pixels * self.orbit_speed)
        rotation = yaw @ self.pose.rotation
        right = rotation[:, 0]
        forward = rotation[:, 2]
        tilt = math.acos(float(np.clip(forward @ self.world_up, -1, 1)))  # 0 = looking straight up
        pitch = dy_pixels * self.orbit_speed
        lo, hi = math.radians(POLE_MARGIN_DEG), math.pi - math.radians(POLE_MARGIN_DEG)
        pitch = float(np.clip(tilt + pitch, lo, hi) - tilt)
        rotation = axis_rotation(right, -pitch) @ rotation  # +angle about right lowers the tilt
        rotation = look_rotation(rotation[:, 2], self.world_up)  # no roll: the scene's up stays vertical
        self.pose.rotation = rotation
        self.pose.eye = target - self.pose.distance * rotation[:, 2]
        self.version += 1

    def zoom(self, steps: float, cursor: tuple[float, float] | None = None,
             size: tuple[int, int] | None = None) -> None:
        """Scroll: move towards (steps > 0) or away from the target by 10 % per step. With the ``cursor``'s pixel
        in a view of ``size`` (width, height), towards the point under the cursor at the target's depth: that point
        stays under the cursor (as in Blender, SuperSplat and map viewers), and the orbit target moves with it."""
        r, distance = self.pose.rotation, self.pose.distance
        ray = r[:, 2]
        if cursor is not None and size is not None and min(size) > 0:
            f = 0.5 * min(size) / math.tan(math.radians(self.pose.fov_y_deg) / 2)  # as ``camera`` does
            u, v = (cursor[0] - size[0] / 2) / f, (cursor[1] - size[1] / 2) / f
            ray = u * r[:, 0] + v * r[:, 1] + r[:, 2]  # to the cursor's point, per unit of depth
        point = self.pose.eye + distance * ray
        self.pose.distance = max(distance * 0.9 ** steps, MIN_DISTANCE)
        self.pose.eye = point - self.pose.distance * ray
        self.version += 1

    def pan(self, dx_pixels: float, dy_pixels: float, viewport_height: int) -> None:
        """Move eye and target in the image plane so the point under the cursor follows it."""
        f = 0.5 * viewport_height / math.tan(math.radians(self.pose.fov_y_deg) / 2)
        scale = self.pose.distance / f
        r = self.pose.rotation
        self.pose.eye = self.pose.eye - scale * (dx_pixels * r[:, 0] + dy_pixels * r[:, 1])
        self.version += 1

    def fly(self, forward: float, right: float, up: float, seconds: float) -> None:
        """WASD/QE: move along the view axis, the right axis and the world up by ``fly_speed`` per second."""
        if forward == right == up == 0:
            return
        r = self.pose.rotation
        step = self.fly_speed * seconds
        self.pose.eye = self.pose.eye + step * (forward * r[:, 2] + right * r[:, 0] + up * self.world_up)
        self.version += 1
