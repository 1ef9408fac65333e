"""Colour-only fast path: with geometry fixed, a render is linear in the Gaussians' colours.

image = W c + T_final * background, W the [pixels x Gaussians] matrix of blend weights alpha_i T_i of one
camera, stored as a sparse CSR matrix (and its transpose for the backward pass).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
import torch
from torch import Tensor

from . import kernels
from .fast import build_tile_lists
from .projection_kernels import project_gaussians_fast


def index_dtype(largest: int) -> type:
    """The CSR index type for a matrix whose counts reach ``largest``: int32 where it fits (a third less memory
    than int64, and torch's sparse product runs faster on it), int64 beyond."""
    return np.int32 if largest < np.iinfo(np.int32).max else np.int64


def _csr(ptr: np.ndarray, cols: np.ndarray, vals: np.ndarray, shape: tuple[int, int]) -> Tensor:
    """A torch CSR tensor over numpy arrays (no copy, invariants not checked: the kernels guarantee them)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Sparse CSR tensor support is in beta")
        return torch.sparse_csr_tensor(torch.from_numpy(ptr), torch.from_numpy(cols), torch.from_numpy(vals),
                                       size=shape, check_invariants=False)


def blend_matrices(walk_args: tuple, n_gaussians: int) -> tuple[Tensor, Tensor, np.ndarray]:
    """The blend-weight matrix W [pixels, Gaussians] of a tile walk (``kernels.count_blend_weights``' arguments),
    its transpose, both CSR with the narrowest index type that holds them, and the final transmittance [H, W]."""
    width, height = walk_args[4], walk_args[5]
    counts, t_final = kernels.count_blend_weights(*walk_args)
    index = index_dtype(max(int(counts.sum()), counts.shape[0], n_gaussians))
    row_ptr = np.zeros(counts.shape[0] + 1, index)
    np.cumsum(counts, out=row_ptr[1:])
    del counts
    cols, vals = kernels.fill_blend_weights(*walk_args, row_ptr, index_dtype=index)
    t_ptr, t_cols, t_vals = kernels.csr_transpose(row_ptr, cols, vals, n_gaussians)
    shape = (height * width, n_gaussians)
    return _csr(row_ptr, cols, vals, shape), _csr(t_ptr, t_cols, t_vals, shape[::-1]), t_final


class SparseProduct(torch.autograd.Function):
    """y = W x for a constant sparse W; the backward multiplies by the stored W^T (``apply(x, W, W^T)``)."""

    @staticmethod
    def forward(ctx, x, weights, weights_t):  # noqa: D401
        ctx.weights_t = weights_t
        return weights @ x

    @staticmethod
    def backward(ctx, grad):
        return ctx.weights_t @ grad.contiguous(), None, None


class ColourCache:
    """Blend weights of one camera for a fixed geometry; ``render(colors)`` costs a sparse product."""

    def __init__(
        self,
        means: Tensor,  # [N, 3]
        quats: Tensor,  # [N, 4]
        scales: Tensor,  # [N, 3]
        opacities: Tensor,  # [N]
        viewmat: Tensor,  # [4, 4]
        K: Tensor,  # [3, 3]
        width: int,
        height: int,
        geometry_version: int,
        near: float = 0.01,
        far: float = 1e10,
        tile_size: int = 16,
    ) -> None:
        self.width, self.height, self.geometry_version = int(width), int(height), int(geometry_version)
        self.n_gaussians = int(means.shape[0])
        with torch.no_grad():
            f32 = torch.float32
            proj = project_gaussians_fast(
                means.to(f32),
                quats.to(f32),
                scales.to(f32),
                viewmat.to(f32),
                K.to(f32),
                self.width,
                self.height,
                near,
                far,
                tile_size,
            )
            features = torch.zeros(self.n_gaussians, kernels.FEATURES)
            lists = build_tile_lists(proj, opacities.to(f32), features)
        args = (lists.offsets, lists.ids, lists.records, lists.tile_order, self.width, self.height, tile_size,
                lists.tiles_x)
        self.weights, self.weights_t, t_final = blend_matrices(args, self.n_gaussians)
        self.t_final = torch.from_numpy(t_final)  # [H, W]

    @property
    def nbytes(self) -> int:
        """Approximate memory held by the two sparse matrices."""
        nnz = int(self.weights.values().shape[0])
        index = self.weights.col_indices().element_size()
        return 2 * nnz * (4 + index) + index * (self.height * self.width + self.n_gaussians + 2)

    def render(self, colors: Tensor, background: Tensor | None = None) -> Tensor:
        """Image [H, W, 3] for colours [N, 3] (float32), differentiable w.r.t. colours and background."""
        if tuple(colors.shape) != (self.n_gaussians, 3):
            raise ValueError(
                f"ColourCache.render: colors must be [{self.n_gaussians}, 3], got {list(colors.shape)}"
            )
        flat = SparseProduct.apply(colors.to(torch.float32), self.weights, self.weights_t)
        image = flat.reshape(self.height, self.width, 3)
        if background is not None:
            image = image + self.t_final[..., None] * background.to(torch.float32)
        return image


class ColourCacheStore:
    """One ColourCache per camera index; all dropped on ``invalidate()`` or a new geometry version."""

    def __init__(self) -> None:
        self._caches: dict[int, ColourCache] = {}
        self.geometry_version: int | None = None

    def __len__(self) -> int:
        return len(self._caches)

    def invalidate(self) -> None:
        """Drop every cache (call after any geometry change)."""
        self._caches.clear()
        self.geometry_version = None

    def get(self, camera_index: int, geometry_version: int) -> ColourCache | None:
        """The camera's cache if built for this geometry version; a new version drops all caches."""
        if geometry_version != self.geometry_version:
            self.invalidate()
            return None
        return self._caches.get(camera_index)

    def put(self, camera_index: int, cache: ColourCache) -> None:
        """Store a cache; a cache of another geometry version than the stored ones replaces them all."""
        if cache.geometry_version != self.geometry_version:
            self.invalidate()
            self.geometry_version = cache.geometry_version
        self._caches[camera_index] = cache

    def get_or_build(
        self, camera_index: int, geometry_version: int, build: Callable[[], ColourCache]
    ) -> ColourCache:
        """Return the stored cache or build, store and return a new one."""
        cache = self.get(camera_index, geometry_version)
        if cache is None:
            cache = build()
            if cache.geometry_version != geometry_version:
                raise ValueError(
                    "ColourCacheStore: built cache has geometry version "
                    f"{cache.geometry_version}, expected {geometry_version}"
                )
            self.put(camera_index, cache)
        return cache
