"""A scene drawn from given cameras by a renderer of its own (the layouts' tests and
``bench/studies/viewer_layouts.py``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import moderngl
import numpy as np

from gstyle_core.cameras.camera import Camera

from .depth_sort import DepthSorter
from .gl_io import read_rgb
from .renderer import DIFFUSE_LAYER, SplatRenderer


def draw_views(ctx: moderngl.Context, arrays: Mapping[str, np.ndarray], cams: Sequence[Camera],
               layout: str = "compact", layer: str = DIFFUSE_LAYER) -> tuple[list[np.ndarray], dict[str, int]]:
    """``arrays`` drawn once from each of ``cams`` by a renderer of its own in ``layout`` (exact depth order, on
    black): the 8-bit images (int16, for differences) and the renderer's GL bytes by part (``gl_memory``)."""
    from .depth_sort import exact_sort_request

    renderer = SplatRenderer(ctx, DepthSorter(exact_sort_request), layout=layout)
    try:
        renderer.set_scene(arrays)
        images = []
        for cam in cams:
            fbo = ctx.framebuffer([ctx.texture((cam.width, cam.height), 4)])
            renderer.render(cam, fbo, (0.0, 0.0, 0.0), layer=layer)
            images.append(read_rgb(fbo).astype(np.int16))
            fbo.color_attachments[0].release()
            fbo.release()
        return images, renderer.gl_memory()
    finally:
        renderer.release()
