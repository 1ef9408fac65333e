"""Reference backend: the 2D half in plain torch with autograd (the oracle for the fast backend).

Tile based like the fast backend (a Gaussian only reaches the tiles its 3-sigma square touches), one tile
at a time, with the list walked in chunks so memory stays bounded (tile pixels x chunk entries).
"""

from __future__ import annotations

import torch
from torch import Tensor

from .kernels import ALPHA_MAX, ALPHA_MIN, TRANSMITTANCE_MIN
from .projection import Projected

ENTRY_CHUNK = 2048


def tile_lists_torch(proj: Projected) -> tuple[Tensor, Tensor]:
    """Depth-sorted per-tile Gaussian lists: (offsets [tiles + 1], gaussian ids [P]), both int64."""
    n_tiles = proj.tiles_x * proj.tiles_y
    visible_ids = torch.nonzero(proj.visible).flatten()
    order = visible_ids[torch.argsort(proj.depths.detach()[visible_ids], stable=True)]
    tmin, tmax = proj.tile_min[order], proj.tile_max[order]
    span = tmax - tmin
    counts = span[:, 0] * span[:, 1]
    gids = order.repeat_interleave(counts)
    first = (torch.cumsum(counts, 0) - counts).repeat_interleave(counts)
    local = torch.arange(gids.shape[0]) - first
    span_x = span[:, 0].repeat_interleave(counts)
    tx = tmin[:, 0].repeat_interleave(counts) + local % span_x.clamp_min(1)
    ty = tmin[:, 1].repeat_interleave(counts) + local // span_x.clamp_min(1)
    tile = ty * proj.tiles_x + tx
    tile_sorted, perm = torch.sort(tile, stable=True)
    offsets = torch.zeros(n_tiles + 1, dtype=torch.int64)
    offsets[1:] = torch.cumsum(torch.bincount(tile_sorted, minlength=n_tiles), 0)
    return offsets, gids[perm]


def _blend_tile(
    pix: Tensor, means2d: Tensor, conics: Tensor, opac: Tensor, feats: Tensor
) -> tuple[Tensor, Tensor]:
    """Blend a tile's pixels [P, 2] over its depth-sorted entries: (features [P, F], T_final [P])."""
    n_pix = pix.shape[0]
    out = torch.zeros(n_pix, feats.shape[1], dtype=feats.dtype)
    trans = torch.ones(n_pix, dtype=feats.dtype)
    done = torch.zeros(n_pix, dtype=torch.bool)
    for s in range(0, means2d.shape[0], ENTRY_CHUNK):
        m, con = means2d[s : s + ENTRY_CHUNK], conics[s : s + ENTRY_CHUNK]
        dx = pix[:, None, 0] - m[None, :, 0]
        dy = pix[:, None, 1] - m[None, :, 1]
        power = -0.5 * (con[:, 0] * dx * dx + con[:, 2] * dy * dy) - con[:, 1] * dx * dy
        alpha = (opac[s : s + ENTRY_CHUNK] * torch.exp(power.clamp(max=0.0))).clamp(max=ALPHA_MAX)
        alpha = torch.where((power <= 0) & (alpha >= ALPHA_MIN), alpha, torch.zeros_like(alpha))
        with torch.no_grad():
            # 3DGS stops a pixel before the entry that would take transmittance below 1e-4.
            t_incl = trans[:, None] * torch.cumprod(1.0 - alpha, 1)
            keep = (t_incl >= TRANSMITTANCE_MIN) & ~done[:, None]
            done = done | ((alpha > 0) & ~keep).any(1)
        alpha = torch.where(keep, alpha, torch.zeros_like(alpha))
        t_after = torch.cumprod(1.0 - alpha, 1)
        t_before = torch.cat([torch.ones_like(t_after[:, :1]), t_after[:, :-1]], 1)
        weights = alpha * t_before * trans[:, None]
        out = out + weights @ feats[s : s + ENTRY_CHUNK]
        trans = trans * t_after[:, -1]
    return out, trans


def blend_reference(
    proj: Projected, opacities: Tensor, features: Tensor, width: int, height: int, tile_size: int
) -> tuple[Tensor, Tensor, dict]:
    """Alpha-blend features [N, F] of projected Gaussians: (features [H, W, F], T_final [H, W], stats)."""
    offsets, gids = tile_lists_torch(proj)
    dtype = features.dtype
    pixel_ids, tile_feats, tile_trans = [], [], []
    for t in range(proj.tiles_x * proj.tiles_y):
        start, end = int(offsets[t]), int(offsets[t + 1])
        if start == end:
            continue
        row0, col0 = (t // proj.tiles_x) * tile_size, (t % proj.tiles_x) * tile_size
        rows = torch.arange(row0, min(row0 + tile_size, height))
        cols = torch.arange(col0, min(col0 + tile_size, width))
        rr, cc = torch.meshgrid(rows, cols, indexing="ij")
        pix = torch.stack([cc.flatten(), rr.flatten()], -1).to(dtype) + 0.5
        ids = gids[start:end]
        f, tr = _blend_tile(pix, proj.means2d[ids], proj.conics[ids], opacities[ids], features[ids])
        pixel_ids.append((rr * width + cc).flatten())
        tile_feats.append(f)
        tile_trans.append(tr)
    feats = torch.zeros(height * width, features.shape[1], dtype=dtype)
    t_final = torch.ones(height * width, dtype=dtype)
    # Keep the outputs in the autograd graph even when no Gaussian is visible (zero gradients, no error).
    anchor = sum(t[:0].sum() for t in (proj.means2d, proj.conics, opacities, features))
    feats, t_final = feats + anchor, t_final + anchor
    if pixel_ids:
        index = torch.cat(pixel_ids)
        feats = feats.index_copy(0, index, torch.cat(tile_feats))
        t_final = t_final.index_copy(0, index, torch.cat(tile_trans))
    return (
        feats.reshape(height, width, -1),
        t_final.reshape(height, width),
        {"tile_pairs": int(gids.shape[0])},
    )
