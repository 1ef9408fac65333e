"""Structural similarity (SSIM) with an 11x11 Gaussian window, as used by the 3DGS loss."""

from __future__ import annotations

import functools

import torch
import torch.nn.functional as F


@functools.lru_cache(maxsize=8)
def _kernel_1d(size: int, sigma: float, dtype: torch.dtype) -> torch.Tensor:
    x = torch.arange(size, dtype=torch.float64) - (size - 1) / 2
    g = torch.exp(-(x**2) / (2 * sigma**2))
    return (g / g.sum()).to(dtype)


def _blur(x: torch.Tensor, size: int, sigma: float) -> torch.Tensor:
    """Separable Gaussian blur of [B, C, H, W] with zero padding (equal to the 2D window, far cheaper)."""
    c = x.shape[1]
    g = _kernel_1d(size, sigma, x.dtype).to(x.device)
    pad = size // 2
    x = F.conv2d(x, g.view(1, 1, 1, size).expand(c, 1, 1, size), padding=(0, pad), groups=c)
    return F.conv2d(x, g.view(1, 1, size, 1).expand(c, 1, size, 1), padding=(pad, 0), groups=c)


def ssim(img1: torch.Tensor, img2: torch.Tensor, window_size: int = 11, sigma: float = 1.5) -> torch.Tensor:
    """Mean SSIM of two images [H, W, C] or [B, C, H, W] in [0, 1] (same-padding, as in the 3DGS code)."""
    if img1.dim() == 3:
        img1 = img1.permute(2, 0, 1)[None]
        img2 = img2.permute(2, 0, 1)[None]
    c = img1.shape[1]
    stats = _blur(torch.cat([img1, img2, img1 * img1, img2 * img2, img1 * img2], dim=1), window_size, sigma)
    mu1, mu2, e11, e22, e12 = stats.split(c, dim=1)
    mu1_sq, mu2_sq, mu12 = mu1 * mu1, mu2 * mu2, mu1 * mu2
    s1, s2, s12 = e11 - mu1_sq, e22 - mu2_sq, e12 - mu12
    c1, c2 = 0.01**2, 0.03**2
    num = (2 * mu12 + c1) * (2 * s12 + c2)
    den = (mu1_sq + mu2_sq + c1) * (s1 + s2 + c2)
    return (num / den).mean()


def psnr(img1: torch.Tensor, img2: torch.Tensor) -> float:
    """Peak signal-to-noise ratio in dB for images in [0, 1]."""
    mse = torch.mean((img1.clamp(0, 1) - img2.clamp(0, 1)) ** 2).item()
    return float("inf") if mse == 0 else -10.0 * float(torch.log10(torch.tensor(mse)))
