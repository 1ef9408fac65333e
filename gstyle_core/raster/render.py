"""The rasterizer entry point: validate inputs, project in torch, blend with the chosen backend."""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from torch import Tensor

from .fast import blend_fast
from .projection import project_gaussians
from .projection_kernels import project_gaussians_fast
from .reference import blend_reference
from .sh import eval_sh_colors

BACKENDS = ("fast", "reference", "gsplat")  # "fast" on CUDA tensors is "gsplat"


def _blend_gsplat(*args):
    from .gsplat_backend import blend_gsplat  # imports gsplat (and builds its module) only when CUDA is used

    return blend_gsplat(*args)


@dataclass
class RenderOutput:
    """What one render returns (see ``rasterize``)."""

    image: Tensor  # [H, W, 3]
    alpha: Tensor  # [H, W] accumulated opacity, 1 - final transmittance
    depth: Tensor  # [H, W] alpha-blended camera z divided by alpha (0 where alpha == 0)
    means2d: Tensor  # [N, 2] pixel coordinates, in the autograd graph (0 for culled Gaussians)
    radii: Tensor  # [N] int32, 0 = culled
    visible: Tensor  # [N] bool
    stats: dict = field(default_factory=dict)


def _check_inputs(
    means, quats, scales, opacities, colors, viewmat, K, width, height, sh_degree, backend, tile_size
):
    n = means.shape[0] if means.ndim == 2 else -1
    expected = {
        "means": (means, (n, 3)),
        "quats": (quats, (n, 4)),
        "scales": (scales, (n, 3)),
        "opacities": (opacities, (n,)),
        "viewmat": (viewmat, (4, 4)),
        "K": (K, (3, 3)),
    }
    for name, (tensor, shape) in expected.items():
        if tuple(tensor.shape) != shape:
            raise ValueError(f"rasterize: {name} must have shape {list(shape)}, got {list(tensor.shape)}")
    if sh_degree is None and tuple(colors.shape) != (n, 3):
        raise ValueError(f"rasterize: colors must be [N, 3] RGB without sh_degree, got {list(colors.shape)}")
    if sh_degree is not None and (colors.ndim != 3 or colors.shape[0] != n):
        raise ValueError(f"rasterize: with sh_degree colors must be [N, K, 3], got {list(colors.shape)}")
    if int(width) < 1 or int(height) < 1:
        raise ValueError(f"rasterize: image size must be at least 1x1, got {width}x{height}")
    if backend not in BACKENDS:
        raise ValueError(f"rasterize: backend must be one of {BACKENDS}, got {backend!r}")
    if int(tile_size) < 1:
        raise ValueError(f"rasterize: tile_size must be positive, got {tile_size}")


def _device_backend(means: Tensor, backend: str) -> str:
    """The blend backend for the tensors' device: "fast" on CUDA is gsplat's (which needs float32 on CUDA)."""
    if means.is_cuda and backend == "fast":
        backend = "gsplat"
    if backend == "gsplat" and (not means.is_cuda or means.dtype != torch.float32):
        raise ValueError("rasterize: the gsplat backend needs float32 tensors on a CUDA device")
    return backend


def _composite(feats: Tensor, t_final: Tensor, background: Tensor | None) -> tuple[Tensor, Tensor, Tensor]:
    """(image over ``background`` (default black), alpha, depth) from the blended colour-and-depth features
    [H, W, 4] and the final transmittance [H, W]; depth is the alpha-normalised mean depth (0 where nothing is)."""
    if background is None:
        background = torch.zeros(3, dtype=feats.dtype, device=feats.device)
    image = feats[..., :3] + t_final[..., None] * background.to(feats.device, feats.dtype)
    alpha = 1.0 - t_final
    has_alpha = alpha > 0
    depth = torch.where(has_alpha, feats[..., 3] / torch.where(has_alpha, alpha, torch.ones_like(alpha)),
                        torch.zeros_like(alpha))
    return image, alpha, depth


def rasterize(
    means: Tensor,  # [N, 3] world positions
    quats: Tensor,  # [N, 4] wxyz, any length (a zero quaternion means identity)
    scales: Tensor,  # [N, 3] activated standard deviations
    opacities: Tensor,  # [N] in [0, 1]
    colors: Tensor,  # [N, 3] RGB, or [N, K, 3] SH coefficients when sh_degree is given
    viewmat: Tensor,  # [4, 4] world-to-camera, OpenCV axes
    K: Tensor,  # [3, 3] intrinsics in pixels
    width: int,
    height: int,
    background: Tensor | None = None,  # [3], default black
    sh_degree: int | None = None,
    near: float = 0.01,
    far: float = 1e10,
    backend: str = "fast",
    tile_size: int = 16,
) -> RenderOutput:
    """Render Gaussians; differentiable w.r.t. means, quats, scales, opacities, colors and background.

    ``backend="fast"`` blends with numba kernels (float32 inside); ``"reference"`` is plain torch autograd and
    keeps the input dtype (float64 works). Both implement the same 3DGS rules; see the package docstring.
    On CUDA tensors ``"fast"`` (or ``"gsplat"``) projects in torch on the GPU and blends with gsplat's kernels
    (``gsplat_backend.py``: float32, alpha clamped at 0.999 instead of 0.99); the outputs stay on the GPU.
    """
    _check_inputs(
        means, quats, scales, opacities, colors, viewmat, K, width, height, sh_degree, backend, tile_size
    )
    width, height, tile_size = int(width), int(height), int(tile_size)
    dtype = means.dtype
    backend = _device_backend(means, backend)
    viewmat = viewmat.detach().to(dtype=dtype, device=means.device)
    # float32: the numba kernels of the projection (forward and backward), shared by both backends so that they
    # agree on culling bit for bit; float64 runs its torch twin (tests/test_raster_projection.py: the two agree)
    # (on CUDA the torch twin runs on the GPU)
    project = project_gaussians_fast if dtype == torch.float32 and not means.is_cuda else project_gaussians
    proj = project(means, quats, scales, viewmat, K, width, height, near, far, tile_size)
    if sh_degree is None:
        rgb = colors
    else:
        camera_position = -viewmat[:3, :3].T @ viewmat[:3, 3]
        rgb = eval_sh_colors(colors, means, camera_position, sh_degree)
    features = torch.cat([rgb.to(dtype), proj.depths[:, None]], 1)
    blend = {"fast": blend_fast, "reference": blend_reference, "gsplat": _blend_gsplat}[backend]
    feats, t_final, stats = blend(proj, opacities.to(dtype), features, width, height, tile_size)
    image, alpha, depth = _composite(feats, t_final, background)
    stats.update(backend=backend, visible=int(proj.visible.sum()), tiles=proj.tiles_x * proj.tiles_y,
                 tiles_x=proj.tiles_x, tiles_y=proj.tiles_y)
    return RenderOutput(image, alpha, depth, proj.means2d, proj.radii, proj.visible, stats)
