"""A scene and its cameras loaded, one camera's image of it rendered, PNGs written and before/after pictures: what
``gstyle render``, ``gstyle stylize``'s pictures, the engine's figures, the studio and the benches share."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .assets import DEMO_SCENE
from .errors import GStyleError


def load_scene_and_cameras(scene_path: str | None, cameras_path: str | None, width: int | None = None):
    """Load a scene (default: the bundled demo) and its cameras: given; else those generated around its input when
    it is a stylized result whose OUT.json records them (``cameras.recorded``); else generated around its Gaussians."""
    from .cameras import generate_cameras, load_cameras
    from .cameras.recorded import recorded_cameras
    from .io import load_scene

    path = Path(scene_path) if scene_path else DEMO_SCENE
    scene, report = load_scene(path)
    if scene.count == 0:
        raise GStyleError(f"{path} holds no Gaussians")
    if cameras_path:
        cams = load_cameras(cameras_path)
    else:
        cams = recorded_cameras(path) or generate_cameras(scene.means, kind="auto")
    if width:
        cams = cams.scaled_to_width(width)
    return scene, report, cams


def save_png(path: str | Path, image: np.ndarray) -> None:
    """Write an [H, W, 3] float image in [0, 1] as an 8-bit PNG, atomically."""
    import io

    from PIL import Image

    from .atomic import atomic_write_bytes

    buf = io.BytesIO()
    Image.fromarray((np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)).save(buf, format="PNG")
    atomic_write_bytes(path, buf.getvalue())


def render_scene_image(scene, camera, backend: str = "fast", sh_degree: int | None = None,
                       with_alpha: bool = False):
    """Render ``scene`` (with its SH unless ``sh_degree`` is lower) from ``camera``; returns [H, W, 3] float32
    (and the [H, W] alpha when ``with_alpha``)."""
    import torch

    from .fit.model import params_from_scene, render_params

    params = params_from_scene(scene, requires_grad=False)
    degree = scene.sh_degree if sh_degree is None else min(sh_degree, scene.sh_degree)
    with torch.no_grad():
        out = render_params(params, camera, sh_degree=degree, backend=backend)
    if with_alpha:
        return out.image.numpy(), out.alpha.numpy()
    return out.image.numpy()


def scene_rows(scenes: list, cameras: list, n_views: int = 3, width: int = 512, margin: int = 8) -> list[np.ndarray]:
    """One strip per scene: renders of the same ``n_views`` cameras spread around the list (not its two ends, which on
    an orbit are neighbours), ``width`` px each, side by side, all cropped to the rows and columns that the first
    scene covers (empty margins of an object on black say nothing)."""
    n = len(cameras)
    if n == 0:
        raise GStyleError("no cameras to render the picture from")
    picks = sorted({int(i * n / min(n_views, n)) for i in range(min(n_views, n))})
    cams = [cameras[i].resized_to_width(width) for i in picks]
    first, alpha = zip(*(render_scene_image(scenes[0], c, with_alpha=True) for c in cams), strict=True)
    strips = [np.concatenate(first, axis=1)]
    strips += [np.concatenate([render_scene_image(scene, c) for c in cams], axis=1) for scene in scenes[1:]]
    covered = np.concatenate(alpha, axis=1) > 1.0 / 255.0
    rows, cols = np.flatnonzero(covered.any(axis=1)), np.flatnonzero(covered.any(axis=0))
    if rows.size and cols.size:
        r0, r1 = max(rows[0] - margin, 0), min(rows[-1] + margin + 1, covered.shape[0])
        c0, c1 = max(cols[0] - margin, 0), min(cols[-1] + margin + 1, covered.shape[1])
        strips = [strip[r0:r1, c0:c1] for strip in strips]
    return strips


def before_after_picture(before_scene, after_scene, cameras: list, n_views: int = 3, width: int = 512,
                         margin: int = 8) -> np.ndarray:
    """Input renders above stylized renders of ``n_views`` cameras (``scene_rows``), cropped to the input's extent."""
    return np.concatenate(scene_rows([before_scene, after_scene], cameras, n_views, width, margin), axis=0)
