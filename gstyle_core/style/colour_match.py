"""Linear colour transfer (as in ARF / G-Style): map the mean and covariance of content colours onto a style's.

c' = A·c + b with A = Σ_s^{1/2} Σ_c^{-1/2} and b = μ_s − A·μ_c. Both matrix square roots come from
symmetric eigendecompositions in float64 with eigenvalues floored at 1e-8 (a spread below 1e-4 in colour
units counts as none), so the result stays finite for singular covariances (uniform or greyscale styles,
one-colour scenes). For a rank-deficient content covariance the floored inverse square root amplifies the
missing directions by at most 1e4; since content colours have (numerically) no spread along them, mapped
colours stay finite. There is no upper clamp: large spreads (any scale of values) are matched exactly.
Colour values beyond ±1e100 are rejected (their covariance would overflow float64).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

EIGEN_MIN = 1e-8
MAX_ABS_VALUE = 1e100


def _as_pixels(colors: np.ndarray, what: str) -> np.ndarray:
    if np.ndim(colors) < 1 or np.shape(colors)[-1] != 3:
        raise ValueError(f"{what} colours must have shape [..., 3], got {np.shape(colors)}")
    pixels = np.asarray(colors, dtype=np.float64).reshape(-1, 3)
    if pixels.shape[0] == 0:
        raise ValueError(f"{what} colours are empty")
    finite = np.isfinite(pixels).all(axis=1)
    if not finite.any():
        raise ValueError(f"{what} colours contain no finite value")
    pixels = pixels[finite]
    if np.abs(pixels).max() > MAX_ABS_VALUE:
        raise ValueError(f"{what} colours exceed ±{MAX_ABS_VALUE:g}")
    return pixels


def _symmetric_power(cov: np.ndarray, power: float) -> np.ndarray:
    values, vectors = np.linalg.eigh((cov + cov.T) / 2)
    values = np.maximum(values, EIGEN_MIN)
    return (vectors * values**power) @ vectors.T


def colour_statistics(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean [3] and (population) covariance [3,3] of ``pixels`` [M,3], float64."""
    pixels = _as_pixels(pixels, "input")
    mean = pixels.mean(axis=0)
    centred = pixels - mean
    return mean, centred.T @ centred / pixels.shape[0]


@dataclass(frozen=True)
class Palette:
    """A style's colour statistics: mean [3] and population covariance [3,3] of its pixels (float64)."""

    mean: np.ndarray
    cov: np.ndarray

    @classmethod
    def of(cls, pixels: np.ndarray) -> Palette:
        """The palette of an image or pixel set [..., 3] (non-finite pixels ignored)."""
        return cls(*colour_statistics(_as_pixels(pixels, "style")))

    @classmethod
    def mixture(cls, palettes: Sequence[Palette], weights: Sequence[float]) -> Palette:
        """The palette of the paintings mixed with ``weights`` (normalised here): the moments of the mixture of their
        pixel distributions, μ = Σ w_i μ_i and Σ = Σ w_i (Σ_i + μ_i μ_iᵀ) − μ μᵀ, as if each painting gave
        that share of the pixels."""
        w = np.asarray(weights, np.float64)
        if len(palettes) == 0 or len(w) != len(palettes) or not (np.isfinite(w).all() and (w >= 0).all()
                                                                  and w.sum() > 0):
            raise ValueError(f"a palette mixture needs one weight >= 0 per palette, not all 0; got {list(weights)}")
        w = w / w.sum()
        mean = sum(wi * p.mean for wi, p in zip(w, palettes, strict=True))
        second = sum(wi * (p.cov + np.outer(p.mean, p.mean)) for wi, p in zip(w, palettes, strict=True))
        cov = second - np.outer(mean, mean)
        return cls(mean, (cov + cov.T) / 2)


def style_palette(style: np.ndarray | Palette) -> Palette:
    """``style`` as a :class:`Palette` (pixels [..., 3] or a palette already)."""
    return style if isinstance(style, Palette) else Palette.of(style)


def colour_transfer_matrix(content_pixels: np.ndarray, style_pixels: np.ndarray | Palette
                           ) -> tuple[np.ndarray, np.ndarray]:
    """(A [3,3], b [3]) in float64 such that A·c + b has the style's mean and covariance (``style_pixels``: the
    painting's pixels [..., 3] or its :class:`Palette`, e.g. the weighted palette of two paintings).
    Non-finite pixels are ignored; empty inputs raise ``ValueError``."""
    mean_c, cov_c = colour_statistics(_as_pixels(content_pixels, "content"))
    palette = style_palette(style_pixels)
    mean_s, cov_s = palette.mean, palette.cov
    transform = _symmetric_power(cov_s, 0.5) @ _symmetric_power(cov_c, -0.5)
    offset = mean_s - transform @ mean_c
    return transform, offset


def apply_colour_transform(colors: np.ndarray, transform: np.ndarray, offset: np.ndarray,
                           clip: bool = True) -> np.ndarray:
    """Apply c' = A·c + b to ``colors`` [..., 3]; ``clip`` (default) clamps the result to [0, 1], the
    displayable range (the reference clamps too). Returns float32 with the input's shape."""
    colors = np.asarray(colors)
    if colors.shape[-1] != 3:
        raise ValueError(f"colours must have shape [..., 3], got {colors.shape}")
    out = colors.astype(np.float64) @ np.asarray(transform, np.float64).T + np.asarray(offset, np.float64)
    if clip:
        out = np.clip(out, 0.0, 1.0)
    return out.astype(np.float32)


def match_colours(content: np.ndarray, style: np.ndarray, clip: bool = True) -> np.ndarray:
    """Colour-match ``content`` [..., 3] (e.g. a set of views) to ``style`` [..., 3] in one call."""
    transform, offset = colour_transfer_matrix(content, style)
    return apply_colour_transform(content, transform, offset, clip=clip)
