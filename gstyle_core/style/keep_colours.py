"""Keep the scene's colours: colour preservation of Gatys et al. 2016 ("Preserving color in neural artistic style
transfer") in YIQ, as the engine's "keep colours" control uses it.

Y = 0.299 R + 0.587 G + 0.114 B is the luminance; I and Q the chroma. The rows of I and Q sum to 0 and Y's to 1,
so adding δ·(1, 1, 1) to an RGB colour changes its luminance by δ and its chroma not at all: every function here
moves colours along (1, 1, 1) only. Used three ways (``engine/stylizer.py``):

* luminance-only colour match (before and after stylization): the luminance mean/std of the scene mapped onto the
  painting's, the chroma kept (an affine map of RGB, like the full colour match);
* luminance-only transfer: VGG (and the CLIP term or its substitute) see the luminance of the render, the content
  view and the painting, each as a grey RGB image;
* per-Gaussian chroma restore: after every optimiser step c_s takes the chroma of c_gt back and keeps its own
  luminance (the gradient of a luminance loss can still move chroma through Adam's per-channel steps and clamps);
  where the new luminance leaves no room for the full chroma in the RGB cube, the hue is kept and the chroma
  reduced as little as fits (``with_chroma_of``).
"""

from __future__ import annotations

import numpy as np
import torch

from .colour_match import Palette

RGB_TO_YIQ = np.array([[0.299, 0.587, 0.114],
                       [0.595716, -0.274453, -0.321263],
                       [0.211456, -0.522591, 0.311135]])
LUMA = RGB_TO_YIQ[0]
MIN_STD = 1e-4  # a luminance spread below this counts as none (as the colour match floors its eigenvalues)


def luminance(rgb: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """Y of colours [..., 3] (numpy or torch, same type back)."""
    if isinstance(rgb, torch.Tensor):
        return rgb @ torch.as_tensor(LUMA, dtype=rgb.dtype)
    return np.asarray(rgb, np.float64) @ LUMA


def chroma(rgb: np.ndarray) -> np.ndarray:
    """(I, Q) of colours [..., 3] → [..., 2] (float64)."""
    return np.asarray(rgb, np.float64) @ RGB_TO_YIQ[1:].T


def grey(rgb: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """The luminance of an image [..., 3] repeated in R, G and B (what VGG sees with keep colours)."""
    y = luminance(rgb)
    if isinstance(rgb, torch.Tensor):
        return y.unsqueeze(-1).expand(*y.shape, 3)
    return np.repeat(y[..., None], 3, axis=-1).astype(np.asarray(rgb).dtype)


def with_chroma_of(colours: torch.Tensor, reference: torch.Tensor) -> torch.Tensor:
    """``colours`` [..., 3] with their own luminance (clamped to [0, 1]) and the hue and chroma of ``reference``
    [..., 3]: Y·(1, 1, 1) + k·(reference − Y_ref·(1, 1, 1)). k = 1 keeps the reference's I and Q exactly; where
    that would leave the RGB cube (a saturated colour made much darker or lighter) k is the largest value that
    fits, so the hue is always kept and the chroma is reduced only as much as the gamut forces."""
    y = luminance(colours).clamp(0.0, 1.0).unsqueeze(-1)
    offset = reference - luminance(reference).unsqueeze(-1)  # the chroma as an RGB offset from grey
    tiny = torch.finfo(offset.dtype).tiny
    room = torch.where(offset > 0, (1.0 - y) / offset.clamp_min(tiny), y / (-offset).clamp_min(tiny))
    k = room.where(offset != 0, torch.ones_like(room)).amin(dim=-1, keepdim=True).clamp(0.0, 1.0)
    return (y + k * offset).clamp(0.0, 1.0)


def luminance_transfer_matrix(content_pixels: np.ndarray, style_pixels: np.ndarray | Palette
                              ) -> tuple[np.ndarray, np.ndarray]:
    """(A [3,3], b [3]) in float64 such that A·c + b has the style's luminance mean and std and c's chroma:
    c' = c + ((a − 1)·Y(c) + β)·(1, 1, 1) with a = σ_s / σ_c, β = μ_s − a·μ_c (σ_c floored at ``MIN_STD``).
    ``style_pixels``: the painting's pixels or its ``Palette`` (μ_s = LUMA·μ, σ_s² = LUMAᵀ Σ LUMA).
    Same form as ``colour_match.colour_transfer_matrix``, so ``apply_colour_transform`` applies it."""
    yc = luminance(_finite(content_pixels, "content"))
    if isinstance(style_pixels, Palette):
        style_mean = float(LUMA @ style_pixels.mean)
        style_std = float(np.sqrt(max(float(LUMA @ style_pixels.cov @ LUMA), 0.0)))
    else:
        ys = luminance(_finite(style_pixels, "style"))
        style_mean, style_std = float(ys.mean()), float(ys.std())
    a = max(style_std, MIN_STD) / max(float(yc.std()), MIN_STD)
    beta = style_mean - a * float(yc.mean())
    ones = np.ones(3)
    return np.eye(3) + (a - 1.0) * np.outer(ones, LUMA), beta * ones


def _finite(pixels: np.ndarray, what: str) -> np.ndarray:
    p = np.asarray(pixels, np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) == 0:
        raise ValueError(f"{what} colours contain no finite value")
    return p
