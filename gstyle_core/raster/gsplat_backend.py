"""The rasterizer's 2D half on CUDA: gsplat's tile intersection and pixel kernels behind our projection.

The projection stays ours (``projection.py``, torch, on the GPU): the same EWA maths, field-of-view clamp, 0.3 px
dilation, culling and square tile radius as the CPU backends, so the two agree on which Gaussian touches which
tile. gsplat (``isect_tiles``, ``isect_offset_encode``, ``rasterize_to_pixels``) sorts, bins and blends; its
backward gives the gradients of means2d, conics, opacities and features, and torch's autograd carries them
through the projection to means, quats and scales.

One rule differs by design: gsplat clamps a Gaussian's alpha at 0.999, the CPU backends (as 3DGS) at 0.99. Where
``opacity · exp(power)`` stays below 0.99 the two blend the same (``tests/test_raster_gsplat.py``); a nearly opaque
Gaussian lets 0.1 % of what is behind it through on the GPU and 1 % on the CPU.

:class:`GsplatColourCache` is the GPU's colour-only path (the CPU's is the sparse-matrix ``ColourCache``): with the
geometry fixed, the projection and the tile lists are made once per camera, and a render is one blend.
"""

from __future__ import annotations

import torch
from torch import Tensor

from .projection import Projected, project_gaussians


def _gsplat():
    from .gsplat_module import ensure_gsplat

    ensure_gsplat()
    from gsplat.cuda import _wrapper

    return _wrapper


def tile_lists(proj: Projected, tile_size: int) -> tuple[Tensor, Tensor]:
    """gsplat's per-tile offsets [1, tiles_y, tiles_x] and flattened Gaussian ids, depth-sorted in each tile."""
    gs = _gsplat()
    radii = torch.where(proj.visible, proj.radii, torch.zeros_like(proj.radii)).to(torch.int32)
    _, isect_ids, flatten_ids = gs.isect_tiles(
        proj.means2d.detach()[None].contiguous(), torch.stack([radii, radii], -1)[None].contiguous(),
        proj.depths.detach().to(torch.float32)[None].contiguous(), tile_size, proj.tiles_x, proj.tiles_y)
    offsets = gs.isect_offset_encode(isect_ids, 1, proj.tiles_x, proj.tiles_y)
    return offsets, flatten_ids


def blend_gsplat(proj: Projected, opacities: Tensor, features: Tensor, width: int, height: int,
                 tile_size: int) -> tuple[Tensor, Tensor, dict]:
    """Blend front to back with gsplat: (feature image [H, W, C], final transmittance [H, W], stats)."""
    gs = _gsplat()
    offsets, flatten_ids = tile_lists(proj, tile_size)
    feats, alphas = gs.rasterize_to_pixels(
        proj.means2d[None], proj.conics.to(torch.float32)[None], features.to(torch.float32)[None],
        opacities.to(torch.float32)[None], width, height, tile_size, offsets, flatten_ids)
    return feats[0], 1.0 - alphas[0, ..., 0], {"entries": int(flatten_ids.shape[0])}


class GsplatColourCache:
    """One camera's fixed geometry on the GPU; ``render(colors)`` blends the given colours (differentiable)."""

    def __init__(self, means: Tensor, quats: Tensor, scales: Tensor, opacities: Tensor, viewmat: Tensor, K: Tensor,
                 width: int, height: int, geometry_version: int, near: float = 0.01, far: float = 1e10,
                 tile_size: int = 16, device: torch.device | str = "cuda") -> None:
        self.width, self.height, self.geometry_version = int(width), int(height), int(geometry_version)
        self.n_gaussians = int(means.shape[0])
        self.tile_size = int(tile_size)
        self.device = torch.device(device)
        f32 = torch.float32
        with torch.no_grad():
            on = [t.detach().to(self.device, f32) for t in (means, quats, scales, viewmat, K)]
            self.proj = project_gaussians(*on, self.width, self.height, near, far, self.tile_size)
            self.opacities = opacities.detach().to(self.device, f32)
            self.offsets, self.flatten_ids = tile_lists(self.proj, self.tile_size)
            ones = torch.ones(self.n_gaussians, 3, device=self.device)
            _, t_final = self._blend(ones)
        self.t_final = t_final.cpu()  # [H, W] on the CPU, as the sparse cache's (coverage, colour matches)

    def _blend(self, colors: Tensor) -> tuple[Tensor, Tensor]:
        gs = _gsplat()
        feats, alphas = gs.rasterize_to_pixels(
            self.proj.means2d[None], self.proj.conics[None], colors[None], self.opacities[None], self.width,
            self.height, self.tile_size, self.offsets, self.flatten_ids)
        return feats[0], 1.0 - alphas[0, ..., 0]

    @property
    def nbytes(self) -> int:
        """GPU memory held: the projection (about 12 floats a Gaussian) and the tile lists."""
        return 4 * 12 * self.n_gaussians + 12 * int(self.flatten_ids.shape[0])

    def render(self, colors: Tensor, background: Tensor | None = None) -> Tensor:
        """Image [H, W, 3] on the GPU for colours [N, 3] (any device; gradients go back to it)."""
        if tuple(colors.shape) != (self.n_gaussians, 3):
            raise ValueError(
                f"GsplatColourCache.render: colors must be [{self.n_gaussians}, 3], got {list(colors.shape)}")
        image, t_final = self._blend(colors.to(self.device, torch.float32).contiguous())
        if background is not None:
            image = image + t_final[..., None] * background.to(self.device, torch.float32)
        return image
