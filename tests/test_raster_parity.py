"""Fast (numba) backend against the pure-torch reference: images and every gradient."""

from __future__ import annotations

import pytest
import torch

from gstyle_core.raster import rasterize
from gstyle_core.raster.synthetic import random_scene

SH_CASES = {"rgb": (None, None), "sh0": (1, 0), "sh3": (16, 3)}


def _render_and_grads(scene, backend, sh_degree, background, weights):
    for p in [*scene.params(), background]:
        p.grad = None
    out = rasterize(
        *scene.params(),
        scene.viewmat,
        scene.K,
        scene.width,
        scene.height,
        background=background,
        sh_degree=sh_degree,
        backend=backend,
    )
    out.means2d.retain_grad()
    w_img, w_alpha, w_depth = weights
    loss = (out.image * w_img).sum() + (out.alpha * w_alpha).sum() + 0.05 * (out.depth * w_depth).sum()
    loss.backward()
    grads = {
        name: p.grad.clone()
        for name, p in zip(("means", "quats", "scales", "opacities", "colors"), scene.params(), strict=True)
    }
    grads["background"] = background.grad.clone()
    grads["means2d"] = out.means2d.grad.clone()
    return out, grads


def _relative(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a - b).norm() / b.norm().clamp_min(1e-12))


def _compare(scene, sh_degree):
    background = torch.tensor([0.2, 0.5, 0.1], requires_grad=True)
    g = torch.Generator().manual_seed(7)
    h, w = scene.height, scene.width
    weights = (
        torch.randn(h, w, 3, generator=g),
        torch.randn(h, w, generator=g),
        torch.randn(h, w, generator=g),
    )
    fast, g_fast = _render_and_grads(scene, "fast", sh_degree, background, weights)
    ref, g_ref = _render_and_grads(scene, "reference", sh_degree, background, weights)
    assert fast.stats["tile_pairs"] == ref.stats["tile_pairs"] > 0
    fast_out = {k: getattr(fast, k).detach() for k in ("image", "alpha", "depth")}
    ref_out = {k: getattr(ref, k).detach() for k in ("image", "alpha", "depth")}
    assert float((fast_out["image"] - ref_out["image"]).abs().max()) <= 1e-4
    assert float((fast_out["alpha"] - ref_out["alpha"]).abs().max()) <= 1e-4
    assert float((fast_out["depth"] - ref_out["depth"]).abs().max()) <= 1e-4 * float(
        ref_out["depth"].abs().max()
    )
    assert torch.equal(fast.radii, ref.radii) and torch.equal(fast.visible, ref.visible)
    for name, g_r in g_ref.items():
        assert float(g_r.norm()) > 0, name
        assert torch.isfinite(g_fast[name]).all(), name
        assert _relative(g_fast[name], g_r) <= 1e-3, (name, _relative(g_fast[name], g_r))
    return fast


@pytest.mark.parametrize("case", list(SH_CASES))
def test_fast_matches_reference(case):
    sh_coeffs, sh_degree = SH_CASES[case]
    # 50x37: tiles partly off the image on two sides.
    scene = random_scene(300, width=50, height=37, seed=3, sh_coeffs=sh_coeffs).requires_grad_()
    out = _compare(scene, sh_degree)
    assert float(out.alpha.detach().mean()) > 0.3  # the scene really covers the image


def test_fast_matches_reference_when_pixels_saturate():
    """Opaque, overlapping Gaussians: pixels hit the 0.99 alpha clamp and stop at transmittance 1e-4."""
    scene = random_scene(400, width=40, height=40, seed=5, scale_range=(0.1, 0.4), spread=0.6)
    scene.opacities = torch.where(torch.arange(400) % 3 == 0, torch.ones(400), 0.6 + 0.4 * scene.opacities)
    scene.requires_grad_()
    out = _compare(scene, None)
    saturated = int((out.alpha.detach() > 0.999).sum())
    assert saturated > 200  # many pixels end at transmittance ~1e-4: early termination exercised


def test_means2d_gradient_only_for_visible():
    scene = random_scene(60, width=32, height=32, seed=11)
    scene.means[:10, 2] = -2.0  # behind the camera
    scene.means[10:20, 0] = 40.0  # far off screen to the right
    scene.requires_grad_()
    for backend in ("fast", "reference"):
        out = rasterize(*scene.params(), scene.viewmat, scene.K, 32, 32, backend=backend)
        out.means2d.retain_grad()
        (out.image * torch.linspace(-1, 1, 32 * 32 * 3).reshape(32, 32, 3)).sum().backward()
        grad_norm = out.means2d.grad.norm(dim=1)
        assert not out.visible[:20].any()
        assert (out.radii[:20] == 0).all() and (out.radii[20:][out.visible[20:]] > 0).all()
        assert (grad_norm[:20] == 0).all()
        assert (grad_norm[out.visible] > 0).float().mean() > 0.9  # a hidden Gaussian may get exactly 0
        for p in scene.params():
            p.grad = None


def test_fast_matches_reference_with_other_tile_size():
    scene = random_scene(150, width=30, height=21, seed=8)
    outs = [
        rasterize(*scene.params(), scene.viewmat, scene.K, 30, 21, backend=b, tile_size=8)
        for b in ("fast", "reference")
    ]
    assert outs[0].stats["tiles"] == 4 * 3
    assert float((outs[0].image - outs[1].image).abs().max()) <= 1e-4
