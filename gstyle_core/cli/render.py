"""``gstyle render``: render one camera of a scene to a PNG (videos and frame folders: ``render_video``)."""

from __future__ import annotations

import argparse

from ..errors import GStyleError
from ..scene_images import load_scene_and_cameras, render_scene_image, save_png

DEFAULT_PNG_OUT = "out/render.png"


def render_command(args: argparse.Namespace) -> int:
    """Run ``gstyle render``: one PNG, or a video / folder of frames (``video.video_command``)."""
    from ..atomic import refuse_overwrite
    from ..outputs import check_writable
    from .video import is_video_request, video_command

    if is_video_request(args):
        return video_command(args)
    args.out = args.out or DEFAULT_PNG_OUT
    index = 0 if args.camera is None else args.camera
    if args.fps is not None:
        raise GStyleError("--fps is for videos (--turntable, --camera-path, or --out FILE.mp4/.gif/DIR/)")
    refuse_overwrite(args.out, args.force, inputs=[args.scene] if args.scene else [])
    check_writable(args.out)
    scene, report, cams = load_scene_and_cameras(args.scene, args.cameras, args.width)
    if not 0 <= index < len(cams.cameras):
        raise GStyleError(f"camera {index} does not exist (there are {len(cams.cameras)})")
    cam = cams.cameras[index]
    image = render_scene_image(scene, cam, args.backend)
    save_png(args.out, image)
    print(f"rendered {report.path if hasattr(report, 'path') else args.scene} ({scene.count} Gaussians) "
          f"from camera {index} of {len(cams.cameras)} ({cams.source}), {cam.width}x{cam.height} -> {args.out}")
    return 0
