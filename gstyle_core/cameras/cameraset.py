"""A set of cameras for one scene, with optional sparse points and ground-truth image paths."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from gstyle_core.cameras.camera import Camera
from gstyle_core.cameras.images import load_image
from gstyle_core.errors import CameraFormatError

SCENE_KINDS = ("forward", "360")


@dataclass
class CameraSet:
    """Cameras of one scene.

    ``kind`` is "forward" (forward-facing, LLFF-like) or "360"; ``source`` says where the cameras came
    from (a path, or "generated-orbit"/"generated-arc"). ``points`` [M,3] and ``point_colors`` [M,3]
    (floats in [0,1]) are sparse points in the same world frame when known (COLMAP points3D, ...).
    ``near``/``far`` are scene depth bounds when the format gives them (LLFF). ``generated``: for generated
    cameras, the parameters that make them again (``generate_cameras``; recorded in a stylized result's OUT.json).
    """

    cameras: list[Camera]
    kind: str
    source: str
    points: np.ndarray | None = None  # [M, 3] float32
    point_colors: np.ndarray | None = None  # [M, 3] float32 in [0, 1]
    near: float | None = None
    far: float | None = None
    generated: dict | None = None

    def __post_init__(self) -> None:
        if self.kind not in SCENE_KINDS:
            raise ValueError(f"scene kind must be one of {SCENE_KINDS}, got {self.kind!r}")

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self) -> Iterator[Camera]:
        return iter(self.cameras)

    def __getitem__(self, index: int) -> Camera:
        return self.cameras[index]

    @property
    def has_images(self) -> bool:
        """True when there is at least one camera and every camera has a ground-truth image path."""
        return bool(self.cameras) and all(c.image_path is not None for c in self.cameras)

    def with_cameras(self, cameras: list[Camera]) -> CameraSet:
        """Same scene metadata (kind, source, points, bounds) with another list of cameras."""
        return replace(self, cameras=list(cameras))

    def split_train_test(self, every: int = 8) -> tuple[CameraSet, CameraSet]:
        """Hold out every ``every``-th camera (indices 0, every, 2*every, ...) as test set (LLFF practice).

        With fewer than two cameras nothing is held out: all cameras train, the test set is empty.
        """
        if every < 2:
            raise ValueError(f"split_train_test: every must be >= 2, got {every}")
        if len(self.cameras) < 2:
            return self.with_cameras(self.cameras), self.with_cameras([])
        test = [c for i, c in enumerate(self.cameras) if i % every == 0]
        train = [c for i, c in enumerate(self.cameras) if i % every != 0]
        return self.with_cameras(train), self.with_cameras(test)

    def scaled_to_width(self, width: int, *, only_shrink: bool = False) -> CameraSet:
        """Every camera rescaled to an image ``width`` pixels wide (aspect kept).

        With ``only_shrink`` cameras already at most ``width`` wide are left unchanged.
        """
        if width < 1:
            raise ValueError(f"scaled_to_width: width must be >= 1, got {width}")
        cams = [c if (only_shrink and c.width <= width) else c.resized_to_width(width) for c in self.cameras]
        return self.with_cameras(cams)

    def load_images(self, max_width: int | None = None, *, background: float = 0.0) -> list[np.ndarray]:
        """Load every camera's ground-truth image as float32 [H, W, 3] in [0, 1], at the camera's size.

        With ``max_width`` images wider than it are downscaled; they then match
        ``self.scaled_to_width(max_width, only_shrink=True)`` (or use :meth:`with_images` to get both).
        Images are read in stored pixel order (no EXIF rotation, as COLMAP calibrates them).
        """
        if max_width is not None:
            return self.scaled_to_width(max_width, only_shrink=True).load_images(background=background)
        cams = self.cameras
        images = []
        for cam in cams:
            if cam.image_path is None:
                raise CameraFormatError(f"camera {cam.name or '?'} has no ground-truth image")
            images.append(load_image(cam.image_path, (cam.width, cam.height),
                                     background=background, exif_orientation=False))
        return images

    def with_images(self, max_width: int | None = None, *,
                    background: float = 0.0) -> tuple[CameraSet, list[np.ndarray]]:
        """Return ``(cameras scaled to at most max_width, their images)``, consistent with each other."""
        cams = self if max_width is None else self.scaled_to_width(max_width, only_shrink=True)
        return cams, cams.load_images(background=background)
