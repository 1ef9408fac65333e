"""Fast backend: the 2D half (sort, bin, blend and its backward) as numba kernels in an autograd Function.

Its torch twin is ``reference.py``; the projection before it is ``projection_kernels.py`` (twin: ``projection.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import torch
from torch import Tensor

from . import kernels
from .projection import Projected


@dataclass
class TileLists:
    """Depth-sorted per-tile Gaussian lists and their contiguous per-entry records."""

    offsets: np.ndarray  # [tiles + 1] int64
    ids: np.ndarray  # [P] int32 Gaussian index of each entry
    records: np.ndarray  # [P, RECORD_FIELDS] float32
    tile_order: np.ndarray  # [tiles] int64 visiting order (load balance)
    tiles_x: int
    tiles_y: int


def _to_numpy32(t: Tensor) -> np.ndarray:
    return np.ascontiguousarray(t.detach().to(torch.float32).cpu().numpy())


def build_tile_lists(proj: Projected, opacities: Tensor, features: Tensor) -> TileLists:
    """Sort visible Gaussians by depth, bin them into tiles and gather per-entry records.

    (The torch twin: ``reference.tile_lists_torch``; ``kernels.depth_order`` is a radix sort.)
    """
    n_tiles = proj.tiles_x * proj.tiles_y
    visible = np.ascontiguousarray(proj.visible.numpy())
    order = kernels.depth_order(_to_numpy32(proj.depths), visible)
    offsets, ids = kernels.bin_gaussians(
        order, proj.tile_min.numpy(), proj.tile_max.numpy(), proj.tiles_x, n_tiles
    )
    per_gaussian = kernels.gaussian_records(
        _to_numpy32(proj.means2d), _to_numpy32(proj.conics), _to_numpy32(opacities), _to_numpy32(features), visible
    )
    records = kernels.gather_records(ids, per_gaussian)
    tile_order = kernels.balanced_tile_order(offsets, numba.get_num_threads())
    return TileLists(offsets, ids, records, tile_order, proj.tiles_x, proj.tiles_y)


class _BlendFunction(torch.autograd.Function):
    """(means2d, conics, opacities, features [N, 4]) -> (feature image [H, W, 4], T_final [H, W])."""

    @staticmethod
    def forward(ctx, means2d, conics, opacities, features, lists, width, height, tile_size):  # noqa: D401
        spans = np.empty((lists.records.shape[0], tile_size, 2), np.int8 if tile_size < 128 else np.int32)
        feats, t_final, last = kernels.blend_forward(
            lists.offsets, lists.records, lists.tile_order, width, height, tile_size, lists.tiles_x, spans
        )
        ctx.lists, ctx.size, ctx.spans = lists, (width, height, tile_size), spans
        ctx.n = means2d.shape[0]
        ctx.dtypes = (means2d.dtype, conics.dtype, opacities.dtype, features.dtype)
        ctx.t_final_np, ctx.last = t_final, last
        dtype = features.dtype
        return torch.from_numpy(feats).to(dtype), torch.from_numpy(t_final).to(dtype)

    @staticmethod
    def backward(ctx, grad_feats, grad_t_final):
        lists: TileLists = ctx.lists
        width, height, tile_size = ctx.size
        if grad_feats is None:
            grad_feats = torch.zeros(height, width, kernels.FEATURES)
        if grad_t_final is None:
            grad_t_final = torch.zeros(height, width)
        entry_grads = kernels.blend_backward(
            lists.offsets,
            lists.records,
            lists.tile_order,
            width,
            height,
            tile_size,
            lists.tiles_x,
            ctx.t_final_np,
            ctx.last,
            ctx.spans,
            _to_numpy32(grad_feats),
            _to_numpy32(grad_t_final),
        )
        per_gaussian = torch.from_numpy(kernels.scatter_entry_grads(lists.ids, entry_grads, ctx.n))
        d_means, d_conics, d_opac, d_feats = ctx.dtypes
        return (
            per_gaussian[:, 0:2].to(d_means),
            per_gaussian[:, 2:5].to(d_conics),
            per_gaussian[:, 5].to(d_opac),
            per_gaussian[:, 6:10].to(d_feats),
            None,
            None,
            None,
            None,
        )


def blend_fast(
    proj: Projected, opacities: Tensor, features: Tensor, width: int, height: int, tile_size: int
) -> tuple[Tensor, Tensor, dict]:
    """Alpha-blend features [N, 4] of projected Gaussians; returns (features [H, W, 4], T_final, stats)."""
    lists = build_tile_lists(proj, opacities, features)
    feats, t_final = _BlendFunction.apply(
        proj.means2d, proj.conics, opacities, features, lists, width, height, tile_size
    )
    return feats, t_final, {"tile_pairs": int(lists.ids.shape[0])}
