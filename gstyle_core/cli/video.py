"""``gstyle render ... --out FILE.mp4|.gif|DIR/``: a video or a folder of frames of any scene.

Frames come from one of: ``--turntable N`` (N views on an orbit around the scene, ``render_video.turntable_cameras``),
``--camera-path camera_path.json`` (nerfstudio's format, ``cameras.camera_path``) or every camera of
``--cameras``; they are rendered and written by ``render_video.render_video``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ..assets import DEMO_SCENE
from ..cameras.camera import Camera
from ..errors import GStyleError
from ..render_video import DEFAULT_FPS, TURNTABLE_SIZE, cameras_up, render_video, turntable_cameras
from ..scene import GaussianScene
from ..video import check_video_output, output_kind

DEFAULT_VIDEO_OUT = "out/turntable.mp4"


def is_video_request(args: argparse.Namespace) -> bool:
    """True when ``gstyle render`` should write a video (or PNG frames) rather than one PNG."""
    if args.turntable is not None or args.camera_path:
        return True
    if args.out is None:
        return False
    text = os.fspath(args.out)
    return text.endswith(("/", os.sep)) or Path(text).is_dir() or Path(text).suffix.lower() in (".mp4", ".gif", "")


def video_cameras(args: argparse.Namespace, scene: GaussianScene) -> tuple[list[Camera], float, str]:
    """The cameras, frame rate and a description of what ``args`` asks for."""
    from ..cameras import load_cameras
    from ..cameras.camera_path import read_camera_path

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

    from ..io import load_scene

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
