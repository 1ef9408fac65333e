"""Reference backend against central finite differences in float64 on a tiny scene."""

from __future__ import annotations

import pytest
import torch

from gstyle_core.raster import rasterize
from gstyle_core.raster.synthetic import random_scene


@pytest.mark.parametrize("sh_coeffs,sh_degree", [(None, None), (4, 1)])
def test_reference_gradients_match_finite_differences(sh_coeffs, sh_degree):
    n = 4 if sh_coeffs is None else 3
    scene = random_scene(
        n,
        width=8,
        height=8,
        seed=2,
        sh_coeffs=sh_coeffs,
        dtype=torch.float64,
        scale_range=(0.5, 1.2),
        spread=1.2,
    )
    scene.opacities = 0.3 + 0.4 * scene.opacities  # away from the 0.99 clamp
    g = torch.Generator().manual_seed(1)
    w_img = torch.randn(8, 8, 3, generator=g, dtype=torch.float64)
    w_alpha = torch.randn(8, 8, generator=g, dtype=torch.float64)
    background = torch.tensor([0.3, 0.2, 0.6], dtype=torch.float64, requires_grad=True)

    def loss(means, quats, scales, opacities, colors, bg):
        out = rasterize(
            means,
            quats,
            scales,
            opacities,
            colors,
            scene.viewmat,
            scene.K,
            8,
            8,
            background=bg,
            sh_degree=sh_degree,
            backend="reference",
        )
        return (out.image * w_img).sum() + (out.alpha * w_alpha).sum() + 0.1 * out.depth.sum()

    inputs = [p.detach().clone().requires_grad_(True) for p in scene.params()] + [background]
    out = rasterize(*inputs[:5], scene.viewmat, scene.K, 8, 8, backend="reference", sh_degree=sh_degree)
    assert out.visible.all() and float(out.alpha.detach().mean()) > 0.2
    assert torch.autograd.gradcheck(loss, inputs, eps=1e-6, atol=1e-6, rtol=1e-4)
