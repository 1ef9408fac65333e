"""Small moderngl helpers the renderer, the studio, the benches and the tests share: reading a framebuffer back,
a texture's dtype name and size, whether the context rasterises on the CPU, a texture's filter and the scissor."""

from __future__ import annotations

import moderngl
import numpy as np

SOFTWARE_GL = ("llvmpipe", "softpipe", "swrast")  # renderer names of GLs that rasterise on the CPU


def is_software_gl(ctx: moderngl.Context) -> bool:
    """The context rasterises on the CPU (Mesa's llvmpipe, softpipe or swrast)."""
    name = str(ctx.info.get("GL_RENDERER", "")).lower()
    return any(word in name for word in SOFTWARE_GL)


def gl_dtype(dtype: np.dtype | type) -> str:
    """moderngl's name of a numpy texture dtype (float16 -> "f2", float32 -> "f4")."""
    return {np.dtype(np.float16): "f2", np.dtype(np.float32): "f4"}[np.dtype(dtype)]


def texture_bytes(tex: moderngl.Texture | moderngl.TextureArray) -> int:
    """Bytes of a texture's texels (layers included)."""
    return tex.width * tex.height * getattr(tex, "layers", 1) * tex.components * int(tex.dtype[1])


def target_size(fbo: moderngl.Framebuffer) -> tuple[int, int]:
    """Drawing size of a framebuffer: its viewport (the window's default framebuffer is resized through it)."""
    x, y, width, height = fbo.viewport
    return int(width), int(height)


def read_rgb(fbo: moderngl.Framebuffer, viewport: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """Read a framebuffer's ``viewport`` (x, y from the bottom, width, height; default: the framebuffer's viewport
    size from its corner) as uint8 [H, W, 3], row 0 = top of the image."""
    x, y, width, height = viewport if viewport is not None else (0, 0, *target_size(fbo))
    data = np.frombuffer(fbo.read(viewport=(x, y, width, height), components=3, alignment=1),
                         np.uint8).reshape(height, width, 3)
    return data[::-1].copy()


def read_rgb_float(fbo: moderngl.Framebuffer) -> np.ndarray:
    """Read a float FBO as float32 [H, W, 3], row 0 = top."""
    width, height = fbo.size
    data = np.frombuffer(fbo.read(components=3, alignment=1, dtype="f4"), np.float32).reshape(height, width, 3)
    return data[::-1].copy()


def set_filter(tex: moderngl.Texture | moderngl.TextureArray, mode: int) -> None:
    """Sample ``tex`` with ``mode`` (``moderngl.NEAREST``, ``moderngl.LINEAR``) when minified and magnified."""
    tex.filter = mode, mode


def set_scissor(ctx: moderngl.Context, rect: tuple[int, int, int, int] | None) -> None:
    """Limit drawing and clearing to ``rect`` (x, y from the bottom, width, height; None: no limit)."""
    ctx.scissor = rect
