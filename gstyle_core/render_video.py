"""``gstyle render ... --out FILE.mp4|.gif|DIR/``: turntable, scene-camera and camera-path videos of any scene.

Frames come from one of: ``--turntable N`` (N views on an orbit around the scene, ``generate_cameras``),
``--camera-path camera_path.json`` (nerfstudio's format, ``cameras.camera_path``) or every camera of
``--cameras``. They are rendered with the CPU rasterizer (SH included) and written by ``video.write_frames``.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from .assets import DEMO_SCENE
from .cameras.camera import Camera
from .errors import GStyleError
from .scene import GaussianScene
from .video import check_video_output, output_kind, write_frames

DEFAULT_FPS = 30.0
DEFAULT_VIDEO_OUT = "out/turntable.mp4"
TURNTABLE_SIZE = (640, 480)
MAX_TURNTABLE_FRAMES = 100_000


def is_video_request(args: argparse.Namespace) -> bool:
    """True when ``gstyle render`` should write a video (or PNG frames) rather than one PNG."""
    if args.turntable is not None or args.camera_path:
        return True
    if args.out is None:
        return False
    text = os.fspath(args.out)
    return text.endswith(("/", os.sep)) or Path(text).is_dir() or Path(text).suffix.lower() in (".mp4", ".gif", "")


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


def video_cameras(args: argparse.Namespace, scene: GaussianScene) -> tuple[list[Camera], float, str]:
    """The cameras, frame rate and a description of what ``args`` asks for."""
    from .cameras import load_cameras
    from .cameras.camera_path import read_camera_path

    if args.turntable is not None and args.camera_path:
        raise GStyleError("--turntable and --camera-path are alternatives; give one")
    if args.camera_path:
        if args.cameras:
            raise GStyleError("--camera-path and --cameras are alternatives; give one")
        path = read_camera_path(args.camera_path)
        cams, fps, what = path.cameras, path.fps, f"camera path {args.camera_path}"
    elif args.turntable is not None:
        size, up = TURNTABLE_SIZE, "-y"
        if args.cameras:
            scene_cams = load_cameras(args.cameras).cameras
            if scene_cams:
                size, up = (scene_cams[0].width, scene_cams[0].height), cameras_up(scene_cams)
        cams, fps, what = turntable_cameras(scene, args.turntable, *size, up=up), DEFAULT_FPS, "turntable"
    elif args.cameras:
        cams, fps, what = list(load_cameras(args.cameras).cameras), DEFAULT_FPS, f"the cameras of {args.cameras}"
        if not cams:
            raise GStyleError(f"{args.cameras} holds no cameras")
    else:
        raise GStyleError("a video needs --turntable N, --camera-path FILE or --cameras (to follow them)")
    if args.width:
        cams = [c.resized_to_width(args.width) for c in cams]
    return cams, float(args.fps) if args.fps else fps, what


def video_command(args: argparse.Namespace) -> int:
    """Run ``gstyle render`` for a video or a folder of frames."""
    from tqdm import tqdm

    from .io import load_scene

    out = args.out or DEFAULT_VIDEO_OUT
    if args.camera is not None:
        raise GStyleError("--camera picks one image; a video follows --turntable, --camera-path or --cameras")
    if args.fps is not None and not 0 < args.fps <= 1000:
        raise GStyleError(f"--fps must be in (0, 1000], got {args.fps}")
    output_kind(out)  # an unknown extension fails before any work
    check_video_output(out, args.force)
    scene_path = Path(args.scene) if args.scene else DEMO_SCENE
    if Path(out).exists() and Path(out).resolve() == scene_path.resolve():
        raise GStyleError(f"refusing to overwrite the input file {out}")
    scene, _report = load_scene(scene_path)
    if scene.count == 0:
        raise GStyleError(f"{scene_path} holds no Gaussians")
    cams, fps, what = video_cameras(args, scene)
    with tqdm(total=len(cams), unit="frame", dynamic_ncols=True, desc="render") as bar:
        count = render_video(scene, cams, out, fps, args.backend, progress=lambda done, total: bar.update(1))
    print(f"rendered {scene_path} ({scene.count} Gaussians) along {what}: {count} frames, "
          f"{cams[0].width}x{cams[0].height} at {fps:g} fps -> {out}")
    return 0
