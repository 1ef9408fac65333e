"""A pinhole camera in the OpenCV/COLMAP convention (x right, y down, z forward)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class Camera:
    """One view: intrinsics in pixels and a 4x4 world-to-camera matrix (OpenCV axes)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    world_to_cam: np.ndarray  # [4, 4] float64
    name: str = ""
    image_path: Path | None = None

    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix."""
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], np.float64)

    @property
    def cam_to_world(self) -> np.ndarray:
        """4x4 camera-to-world matrix."""
        return np.linalg.inv(self.world_to_cam)

    @property
    def position(self) -> np.ndarray:
        """Camera centre in world coordinates."""
        return self.cam_to_world[:3, 3].copy()

    @property
    def forward(self) -> np.ndarray:
        """Unit viewing direction (camera +z) in world coordinates."""
        f = self.cam_to_world[:3, 2]
        return f / np.linalg.norm(f)

    def scaled(self, factor: float) -> Camera:
        """Return the same camera for an image resized by ``factor``."""
        w = max(1, int(round(self.width * factor)))
        h = max(1, int(round(self.height * factor)))
        sx, sy = w / self.width, h / self.height
        return Camera(w, h, self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy,
                      self.world_to_cam.copy(), self.name, self.image_path)

    def resized_to_width(self, width: int) -> Camera:
        """Return the camera scaled so its image is ``width`` pixels wide (aspect kept)."""
        return self.scaled(width / self.width)

    def cropped(self, x0: int, y0: int, width: int, height: int) -> Camera:
        """The camera of the pixel window [x0, x0 + width) × [y0, y0 + height) of this camera's image: the same pose
        and focal lengths, the principal point moved by the window's corner (a render of it is that part of this
        camera's render)."""
        if width < 1 or height < 1:
            raise ValueError(f"a crop needs a size of at least 1 × 1 px, got {width} × {height}")
        return Camera(int(width), int(height), self.fx, self.fy, self.cx - x0, self.cy - y0, self.world_to_cam.copy(),
                      self.name, self.image_path)
