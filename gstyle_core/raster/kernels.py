"""The numba kernels of the fast backend's 2D half, in one namespace (``fast.py`` and ``colour_cache.py`` use them
as ``kernels.NAME``): binning and records (``tile_kernels``), blending and its backward (``blend_kernels``), blend
weights (``weight_kernels``), on the record layout and per-pixel bounds of ``pixel_kernels``.
"""

from __future__ import annotations

from .blend_kernels import blend_backward, blend_forward, scatter_entry_grads
from .pixel_kernels import (
    ALPHA_MAX,
    ALPHA_MIN,
    FEATURES,
    GRAD_FIELDS,
    POWER_REJECT,
    RECORD_FIELDS,
    TRANSMITTANCE_MIN,
)
from .tile_kernels import (
    balanced_tile_order,
    bin_gaussians,
    depth_order,
    gather_records,
    gaussian_records,
    reach_boxes,
)
from .weight_kernels import count_blend_weights, csr_transpose, fill_blend_weights

__all__ = [
    "ALPHA_MAX",
    "ALPHA_MIN",
    "FEATURES",
    "GRAD_FIELDS",
    "POWER_REJECT",
    "RECORD_FIELDS",
    "TRANSMITTANCE_MIN",
    "balanced_tile_order",
    "bin_gaussians",
    "blend_backward",
    "blend_forward",
    "count_blend_weights",
    "csr_transpose",
    "depth_order",
    "fill_blend_weights",
    "gather_records",
    "gaussian_records",
    "reach_boxes",
    "scatter_entry_grads",
]
