"""CPU-side preparation of per-Gaussian data for the GL splat renderer (pure numpy, no GL)."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING

import numpy as np

from gstyle_core.scene import SH_C0, importance_order, sigmoid

if TYPE_CHECKING:
    from gstyle_core.scene import GaussianScene

TEXTURE_WIDTH = 4096  # Gaussians per texture row; data lives in RGBA textures (no SSBO size limit)
GEOMETRY_KEYS = ("means", "log_scales", "quats", "opacity_logits")
HALF_MAX = 65504.0  # the largest finite half float
MAX_SCALE_EXPONENT = 30  # |k| of the scales' power of two (``scale_exponent``); 2^-k stays a normal float32

# Per-Gaussian texture layouts of the renderer (bytes a Gaussian: geometry + a colour layer + SH of degree 3):
# "compact": mean and opacity RGBA32F, unit quaternion and scales (times the scene's power of two) RGBA16F,
#            colours and SH coefficients RGBA16F: 32 + 8 + 96;
# "float32": mean and opacity, and the three columns of M = R S, RGBA32F; colours and SH RGBA32F: 64 + 16 + 192.
LAYOUTS = ("compact", "float32")


def rotation_matrices(quats: np.ndarray) -> np.ndarray:
    """[N, 3, 3] rotations from wxyz quaternions of any length (a zero quaternion means identity)."""
    w, x, y, z = unit_quaternions(quats).T
    return np.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], axis=-1).reshape(-1, 3, 3)


def check_geometry(arrays: Mapping[str, np.ndarray]) -> int:
    """Validate geometry arrays and return N; raises ValueError with a one-line reason."""
    missing = [k for k in GEOMETRY_KEYS if k not in arrays]
    if missing:
        raise ValueError(f"scene arrays lack {', '.join(missing)}")
    n = int(np.shape(arrays["means"])[0])
    shapes = {"means": (n, 3), "log_scales": (n, 3), "quats": (n, 4), "opacity_logits": (n,)}
    for key, shape in shapes.items():
        if tuple(np.shape(arrays[key])) != shape:
            raise ValueError(f"{key} must have shape {list(shape)}, got {list(np.shape(arrays[key]))}")
    return n


def texture_rows(n: int) -> int:
    """Rows of a TEXTURE_WIDTH-wide texture holding n Gaussians (at least 1)."""
    return max(1, -(-n // TEXTURE_WIDTH))


def pack_rgba(columns: np.ndarray, dtype: type = np.float32) -> np.ndarray:
    """[N, C<=4] float data -> zero-padded [rows, TEXTURE_WIDTH, 4] texture content of ``dtype`` (float32, or
    float16 with values beyond the half range clipped to it)."""
    n = columns.shape[0]
    out = np.zeros((texture_rows(n) * TEXTURE_WIDTH, 4), dtype)
    if out.dtype == np.float16:
        columns = np.clip(columns, -HALF_MAX, HALF_MAX)
    out[:n, : columns.shape[1]] = columns
    return out.reshape(-1, TEXTURE_WIDTH, 4)


def check_layout(layout: str) -> str:
    """``layout`` if it is one of ``LAYOUTS``; a one-line ValueError otherwise."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown texture layout {layout!r}; have {', '.join(LAYOUTS)}")
    return layout


def texture_dtype(layout: str) -> type:
    """numpy dtype of the colour and SH textures of a layout."""
    return np.float16 if check_layout(layout) == "compact" else np.float32


def geometry_textures(arrays: Mapping[str, np.ndarray], layout: str = "float32") -> tuple[list[np.ndarray], float]:
    """Texture contents of the geometry in ``layout`` and the unit of its stored scales (see ``LAYOUTS``).

    "float32": (mean, opacity) and the three columns of M = R S (Sigma_3D = M M^T), unit 1. "compact": (mean,
    opacity) float32, then the unit quaternion and the scales times 2^k as half floats, unit 2^-k
    (``scale_exponent``). Non-finite Gaussians get opacity 0 (the documented repair: they vanish)."""
    check_geometry(arrays)
    check_layout(layout)
    means = np.asarray(arrays["means"], np.float32)
    opacity = sigmoid(np.asarray(arrays["opacity_logits"], np.float32))
    # float64 for the float32 layout's matrices; float32 is ample for what is stored as half floats (and halves the
    # temporary arrays of opening a scene of millions)
    work = np.float64 if layout == "float32" else np.float32
    with np.errstate(over="ignore"):  # an absurd log-scale overflows to inf: that Gaussian is repaired away below
        scales = np.exp(np.asarray(arrays["log_scales"], work))
    if layout == "float32":
        factor = rotation_matrices(arrays["quats"]) * scales[:, None, :]
        finite = np.isfinite(factor).all((1, 2))
    else:
        factor = unit_quaternions(arrays["quats"], np.float32)
        finite = np.isfinite(scales).all(1) & np.isfinite(factor).all(1)
    bad = ~(np.isfinite(means).all(1) & finite & np.isfinite(opacity))
    opacity = np.where(bad, 0.0, opacity).astype(np.float32)
    means = np.where(bad[:, None], 0.0, means)
    first = pack_rgba(np.column_stack([means, opacity]))
    if layout == "float32":
        m = np.where(bad[:, None, None], 0.0, factor).astype(np.float32)
        return [first, pack_rgba(m[:, :, 0]), pack_rgba(m[:, :, 1]), pack_rgba(m[:, :, 2])], 1.0
    k = scale_exponent(scales)
    stored = np.where(bad[:, None], 0.0, scales) * 2.0**k
    factor[bad] = (1.0, 0.0, 0.0, 0.0)
    return [first, pack_rgba(factor, np.float16), pack_rgba(stored, np.float16)], 2.0**-k


def unit_quaternions(quats: np.ndarray, dtype: type = np.float64) -> np.ndarray:
    """[N, 4] wxyz quaternions of ``dtype`` scaled to length 1 (length zero or NaN: identity)."""
    q = np.asarray(quats, dtype)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(norm > 0, q / np.where(norm > 0, norm, 1), np.array([1, 0, 0, 0], dtype))


def scale_exponent(scales: np.ndarray, sample: int = 100_000) -> int:
    """k such that the scales times 2^k suit half floats: their median (of up to ``sample`` of them) near 1,
    the largest at most 2^15; |k| <= MAX_SCALE_EXPONENT. Half floats keep 11 significant bits from 6.1e-5 to
    65504, so the scales of a scene in any unit keep their relative precision (2^-11) unless they span more
    than 2^30."""
    flat = np.asarray(scales, np.float64).reshape(-1)
    positive = flat[np.isfinite(flat) & (flat > 0)]
    if not positive.size:
        return 0
    middle = float(np.median(positive[:: max(1, positive.size // sample)]))
    k = min(round(-math.log2(middle)), math.floor(15 - math.log2(float(positive.max()))))
    return int(np.clip(k, -MAX_SCALE_EXPONENT, MAX_SCALE_EXPONENT))


def colors_from_arrays(arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """Diffuse RGB [N, 3]: ``colors`` if given, else 0.5 + SH_C0 * ``sh_dc``."""
    if "colors" in arrays:
        return np.asarray(arrays["colors"], np.float32)
    if "sh_dc" in arrays:
        return (0.5 + SH_C0 * np.asarray(arrays["sh_dc"], np.float32)).astype(np.float32)
    raise ValueError("scene arrays need 'colors' [N,3] or 'sh_dc' [N,3]")


def view_depths(means: np.ndarray, world_to_cam: np.ndarray) -> np.ndarray:
    """Camera-space z of each mean."""
    r = np.asarray(world_to_cam, np.float64)
    return np.asarray(means, np.float64) @ r[2, :3] + r[2, 3]


def back_to_front_order(means: np.ndarray, world_to_cam: np.ndarray, near: float) -> np.ndarray:
    """int32 indices of the Gaussians in front of the near plane, farthest first."""
    z = view_depths(means, world_to_cam)
    visible = np.flatnonzero(np.isfinite(z) & (z > near))
    order = visible[np.argsort(-z[visible], kind="stable")]
    return order.astype(np.int32)


def importance_ranks(log_scales: np.ndarray, opacity_logits: np.ndarray) -> np.ndarray:
    """int32 rank of each Gaussian in ``importance_order`` (0 = most important)."""
    order = importance_order(log_scales, opacity_logits)
    ranks = np.empty(order.shape[0], np.int32)
    ranks[order] = np.arange(order.shape[0], dtype=np.int32)
    return ranks


def sh_texture_layers(sh_dc: np.ndarray, sh_rest: np.ndarray, dtype: type = np.float32) -> Iterator[np.ndarray]:
    """Texture contents ([rows, TEXTURE_WIDTH, 4] of ``dtype``) of SH coefficients, one texture-array layer at a
    time.

    A Gaussian's coefficients are laid out coefficient-major, ``dc.rgb, rest[0].rgb, rest[1].rgb, ...`` (3 (d+1)^2
    floats, zero-padded to a multiple of 4); layer j holds floats 4j..4j+3 (``shaders/splat_project.vert``)."""
    sh_dc = np.asarray(sh_dc, np.float32)
    sh_rest = np.asarray(sh_rest, np.float32).reshape(sh_dc.shape[0], -1, 3)
    floats = 3 * (sh_rest.shape[1] + 1)
    for j in range(-(-floats // 4)):
        columns = np.zeros((sh_dc.shape[0], 4), np.float32)
        for c in range(4):
            f = 4 * j + c
            if f < floats:
                k, channel = divmod(f, 3)
                columns[:, c] = sh_dc[:, channel] if k == 0 else sh_rest[:, k - 1, channel]
        yield pack_rgba(columns, dtype)


def sh_colors(sh: np.ndarray, means: np.ndarray, camera_position: np.ndarray) -> np.ndarray:
    """View-dependent RGB [N, 3] from SH coefficients [N, (d+1)^2, 3] seen from ``camera_position``.

    Uses the rasterizer's own evaluation (3DGS order/constants, +0.5, clamp at 0), so both renderers agree.
    """
    import torch

    from gstyle_core.raster.sh import eval_sh_colors
    from gstyle_core.scene import sh_degree_from_rest_count

    degree = sh_degree_from_rest_count(sh.shape[1] - 1)
    with torch.no_grad():
        rgb = eval_sh_colors(torch.from_numpy(np.ascontiguousarray(sh, np.float32)),
                             torch.from_numpy(np.ascontiguousarray(means, np.float32)),
                             torch.tensor(np.asarray(camera_position, np.float32)), degree)
    return rgb.numpy()


def scene_arrays(scene: GaussianScene) -> dict[str, np.ndarray]:
    """GaussianScene -> the renderer's array dict (with SH)."""
    return {"means": scene.means, "log_scales": scene.log_scales, "quats": scene.quats,
            "opacity_logits": scene.opacity_logits, "sh_dc": scene.sh_dc, "sh_rest": scene.sh_rest}
