"""Random Gaussian scenes and a simple camera, for tests and benchmarks."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor


@dataclass
class SyntheticScene:
    """Rasterizer inputs: Gaussians (activated parameters) and one camera."""

    means: Tensor
    quats: Tensor
    scales: Tensor
    opacities: Tensor
    colors: Tensor
    viewmat: Tensor
    K: Tensor
    width: int
    height: int

    def params(self) -> list[Tensor]:
        """The differentiable inputs, in rasterize's argument order."""
        return [self.means, self.quats, self.scales, self.opacities, self.colors]

    def requires_grad_(self) -> SyntheticScene:
        """Make every Gaussian parameter a leaf that records gradients; returns self."""
        for p in self.params():
            p.requires_grad_(True)
        return self


def random_scene(
    n: int,
    width: int = 64,
    height: int = 64,
    seed: int = 0,
    sh_coeffs: int | None = None,
    dtype: torch.dtype = torch.float32,
    scale_range: tuple[float, float] = (0.02, 0.15),
    spread: float = 1.0,
) -> SyntheticScene:
    """n Gaussians in a box of half-side ``spread`` around z = 4 in front of a camera at the origin.

    ``sh_coeffs``: None for RGB colours [N, 3], else SH coefficients [N, sh_coeffs, 3].
    """
    g = torch.Generator().manual_seed(seed)

    def uniform(*shape: int, lo: float = 0.0, hi: float = 1.0) -> Tensor:
        return lo + (hi - lo) * torch.rand(*shape, generator=g, dtype=torch.float64)

    means = uniform(n, 3, lo=-spread, hi=spread) + torch.tensor([0.0, 0.0, 4.0], dtype=torch.float64)
    log_lo, log_hi = torch.log(torch.tensor(scale_range, dtype=torch.float64))
    scales = torch.exp(uniform(n, 3, lo=float(log_lo), hi=float(log_hi)))
    quats = torch.randn(n, 4, generator=g, dtype=torch.float64)
    opacities = uniform(n, lo=0.05, hi=0.95)
    if sh_coeffs is None:
        colors = uniform(n, 3)
    else:
        colors = 0.4 * torch.randn(n, sh_coeffs, 3, generator=g, dtype=torch.float64)
        colors[:, 0] += 1.0
    focal = 1.1 * max(width, height)
    K = torch.tensor([[focal, 0.0, width / 2], [0.0, focal, height / 2], [0.0, 0.0, 1.0]], dtype=dtype)
    viewmat = torch.eye(4, dtype=dtype)
    return SyntheticScene(
        means.to(dtype),
        quats.to(dtype),
        scales.to(dtype),
        opacities.to(dtype),
        colors.to(dtype),
        viewmat,
        K,
        width,
        height,
    )
