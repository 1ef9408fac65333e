"""The loss terms computed on the render's pixels, beside the network terms of ``losses.py``: total variation (the
paper's), colour smoothness and edges kept (this project's). Each takes a render [B, 3, H, W] at its own size."""

from __future__ import annotations

import torch


def tv_loss(img: torch.Tensor, kind: str = "squared") -> torch.Tensor:
    """Total variation of ``img`` [B,3,H,W], **summed** over pixels, channels and the batch:
    Σ (Δ_x)² + Σ (Δ_y)² (``kind="squared"``, the G-Style reference) or Σ|Δ_x| + Σ|Δ_y| (``kind="abs"``)."""
    dx = img[..., :, 1:] - img[..., :, :-1]
    dy = img[..., 1:, :] - img[..., :-1, :]
    if kind == "squared":
        return (dx * dx).sum() + (dy * dy).sum()
    if kind == "abs":
        return dx.abs().sum() + dy.abs().sum()
    raise ValueError(f"tv kind must be 'squared' or 'abs', got {kind!r}")


def opponent_chroma(img: torch.Tensor) -> torch.Tensor:
    """[B, 3, H, W] RGB → [B, 2, H, W] opponent chroma r − g and (r + g)/2 − b (``style/speckle.py``'s channels)."""
    r, g, b = img[:, 0], img[:, 1], img[:, 2]
    return torch.stack([r - g, 0.5 * (r + g) - b], dim=1)


def luminance(img: torch.Tensor) -> torch.Tensor:
    """[B, 3, H, W] RGB → [B, H, W] luminance (Rec. 601 weights)."""
    return 0.299 * img[:, 0] + 0.587 * img[:, 1] + 0.114 * img[:, 2]


def neighbour_differences(planes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Differences of horizontally and vertically neighbouring pixels of ``planes`` [..., H, W]."""
    return planes[..., :, 1:] - planes[..., :, :-1], planes[..., 1:, :] - planes[..., :-1, :]


def pairs_mean(dx: torch.Tensor, dy: torch.Tensor, coverage: torch.Tensor | None) -> torch.Tensor:
    """The mean squared value of per-pair quantities ``dx`` [B, C, H, W-1] and ``dy`` [B, C, H-1, W] (horizontal and
    vertical pairs of pixels, the two means summed). With ``coverage`` ([H, W] in [0, 1]) each pair, its C channels
    summed, is weighted by the product of its two pixels' coverage, so the scene's silhouette against an empty
    background does not count. A mean, not a sum: a weight on it means the same at every render size."""
    if coverage is None:
        return (dx * dx).mean() + (dy * dy).mean()
    w = torch.as_tensor(coverage, dtype=dx.dtype).reshape(dx.shape[-2], dy.shape[-1])
    wx, wy = w[:, 1:] * w[:, :-1], w[1:, :] * w[:-1, :]
    eps, batch = 1e-8, dx.shape[0]
    return ((dx * dx).sum(1) * wx).sum() / (wx.sum() * batch + eps) + \
        ((dy * dy).sum(1) * wy).sum() / (wy.sum() * batch + eps)


def chroma_tv_loss(img: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
    """Colour smoothness: the mean squared difference of the opponent chroma of neighbouring pixels of ``img``
    [B, 3, H, W] (``pairs_mean``, weighted by ``coverage``). Luminance is left free: edges and shading carry the
    scene's structure."""
    return pairs_mean(*neighbour_differences(opponent_chroma(img)), coverage)


def edges_loss(img: torch.Tensor, gt: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
    """Edges kept: the mean squared difference between the luminance gradients (differences of neighbouring pixels,
    horizontal and vertical) of ``img`` and of ``gt`` (its content target), both [B, 3, H, W] (``pairs_mean``,
    weighted by ``coverage``). The painting's colours and the texture NNFM adds may change everything but where the
    scene's light and dark edges lie and how strong they are (a gradient-domain content term, after Li et al.'s
    Laplacian-steered style transfer, 2017)."""
    (ix, iy), (gx, gy) = neighbour_differences(luminance(img)), neighbour_differences(luminance(gt.to(img.dtype)))
    return pairs_mean((ix - gx)[:, None], (iy - gy)[:, None], coverage)
