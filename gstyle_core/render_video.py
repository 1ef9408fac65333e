"""Turntable, scene-camera and camera-path videos of any scene: cameras on an orbit (``turntable_cameras``), frames
rendered with the CPU rasterizer (SH included) and written by ``video.write_frames`` (``render_video``). The studio's
video export and ``gstyle render --out FILE.mp4|.gif|DIR/`` (``cli/video.py``) use it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence

import numpy as np

from .cameras.camera import Camera
from .errors import GStyleError
from .scene import GaussianScene
from .video import output_kind, write_frames

DEFAULT_FPS = 30.0
TURNTABLE_SIZE = (640, 480)
MAX_TURNTABLE_FRAMES = 100_000


def turntable_cameras(scene: GaussianScene, count: int, width: int = TURNTABLE_SIZE[0],
                      height: int = TURNTABLE_SIZE[1], up: str | np.ndarray = "-y") -> list[Camera]:
    """``count`` views evenly around the scene on an orbit 20 degrees above its horizon (the directions of
    ``generate_cameras``' orbit), looking at the centre of the scene's robust box from the one distance that frames
    the whole box with a margin in every frame (``cameras.framing``: the subject never touches the frame's edge)."""
    from .cameras import generate_cameras
    from .cameras.framing import frame_cameras, scene_box
    from .cameras.generate import finite_points, resolve_up, robust_centre_radius

    if not 1 <= count <= MAX_TURNTABLE_FRAMES:
        raise GStyleError(f"--turntable needs 1 to {MAX_TURNTABLE_FRAMES:,} frames, got {count}")
    orbit = generate_cameras(scene.means, kind="orbit", count=count, width=width, height=height, up=up).cameras
    pts = finite_points(scene.means)
    up_vec = resolve_up(up, pts, robust_centre_radius(pts)[0])  # the orbit's up, as generate_cameras found it
    return frame_cameras(orbit, *scene_box(scene.means), up_vec)


def cameras_up(cameras: Sequence[Camera]) -> np.ndarray:
    """The scene's up axis from its cameras (``cameras.up.estimate_up``), to orbit the way they stand."""
    from .cameras.up import estimate_up

    return estimate_up(cameras)


def frame_iterator(scene: GaussianScene, cameras: Sequence[Camera], backend: str = "fast",
                   progress: Callable[[int, int], None] | None = None) -> Iterator[np.ndarray]:
    """Render ``cameras`` one after the other ([H, W, 3] float32 each, SH evaluated); ``progress(done, total)``
    is called after each frame."""
    import torch

    from .fit.model import params_from_scene, render_params

    params = params_from_scene(scene, requires_grad=False)
    total = len(cameras)
    for i, cam in enumerate(cameras):
        with torch.no_grad():
            image = render_params(params, cam, sh_degree=scene.sh_degree, backend=backend).image.numpy()
        yield image
        if progress is not None:
            progress(i + 1, total)


def render_video(scene: GaussianScene, cameras: Sequence[Camera], out: str | os.PathLike, fps: float = DEFAULT_FPS,
                 backend: str = "fast", progress: Callable[[int, int], None] | None = None,
                 cancelled: Callable[[], bool] | None = None) -> int:
    """Render ``scene`` from every camera into ``out`` (.mp4, .gif or a folder of PNGs); returns the frame count.

    Nothing is written if any frame fails or ``cancelled()`` turns True (``video.Cancelled``)."""
    if not cameras:
        raise GStyleError("no cameras to render a video from")
    if output_kind(out) != "dir":
        sizes = {(c.width, c.height) for c in cameras}
        if len(sizes) > 1:
            raise GStyleError(f"the cameras have {len(sizes)} different image sizes; a video needs one "
                              "(write a folder of PNG frames, or pass --width for one width)")
    return write_frames(frame_iterator(scene, cameras, backend, progress), out, fps, cancelled)
