"""The pixel terms' closed-form gradients (``SquaredVariation``, ``LinearPairsMean``) against autograd through plain
slices, written out here as the terms are defined, in float64 with ``gradcheck`` and in float32 as the loss runs."""

from __future__ import annotations

import pytest
import torch
from bench_cli import load_bench

from gstyle_core.style.pixel_terms import (
    SquaredVariation,
    adjoint_differences,
    chroma_tv_loss,
    edges_loss,
    luminance,
    opponent_chroma,
    tv_loss,
)


def _differences(planes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    return planes[..., :, 1:] - planes[..., :, :-1], planes[..., 1:, :] - planes[..., :-1, :]


def _pairs_mean(dx: torch.Tensor, dy: torch.Tensor, coverage: torch.Tensor | None) -> torch.Tensor:
    """The definition: each pair's squared difference (channels summed) weighted by its two pixels' coverage, over
    the weight times the batch; without coverage the plain mean over every pair, channel and image."""
    if coverage is None:  # a render one pixel wide (or high) has no pairs that way: they add nothing
        return sum((d * d).mean() if d.numel() else d.sum() for d in (dx, dy))
    wx, wy = coverage[:, 1:] * coverage[:, :-1], coverage[1:, :] * coverage[:-1, :]
    batch = dx.shape[0]
    return (((dx * dx).sum(1) * wx).sum() / (wx.sum() * batch + 1e-8)
            + ((dy * dy).sum(1) * wy).sum() / (wy.sum() * batch + 1e-8))


def _reference_chroma(img, coverage):
    return _pairs_mean(*_differences(opponent_chroma(img)), coverage)


def _reference_edges(img, gt, coverage):
    (ix, iy), (gx, gy) = _differences(luminance(img)), _differences(luminance(gt))
    return _pairs_mean((ix - gx)[:, None], (iy - gy)[:, None], coverage)


def _reference_tv(img):
    dx, dy = _differences(img)
    return (dx * dx).sum() + (dy * dy).sum()


SIZES = [(2, 7, 9), (1, 1, 6), (1, 5, 1), (3, 2, 2)]


def _inputs(batch, h, w, dtype, seed=0):
    gen = torch.Generator().manual_seed(seed)
    img = torch.rand(batch, 3, h, w, generator=gen, dtype=dtype).requires_grad_(True)
    gt = torch.rand(batch, 3, h, w, generator=gen, dtype=dtype)
    coverage = torch.rand(h, w, generator=gen, dtype=dtype) * (torch.rand(h, w, generator=gen) > 0.3)
    return img, gt, coverage


@pytest.mark.parametrize("size", SIZES, ids=[f"{b}x{h}x{w}" for b, h, w in SIZES])
@pytest.mark.parametrize("covered", [False, True], ids=["whole frame", "coverage"])
def test_the_closed_form_gradients_pass_gradcheck(size, covered):
    img, gt, coverage = _inputs(*size, torch.float64)
    cov = coverage if covered else None
    assert torch.autograd.gradcheck(lambda x: chroma_tv_loss(x, cov), (img,))
    assert torch.autograd.gradcheck(lambda x: edges_loss(x, gt, cov), (img,))
    if not covered:
        assert torch.autograd.gradcheck(tv_loss, (img,))


@pytest.mark.parametrize("size", SIZES, ids=[f"{b}x{h}x{w}" for b, h, w in SIZES])
@pytest.mark.parametrize("covered", [False, True], ids=["whole frame", "coverage"])
def test_the_terms_and_their_gradients_are_the_definitions(size, covered):
    cov_of = (lambda c: c) if covered else (lambda c: None)
    for term, reference in [(lambda x, g, c: chroma_tv_loss(x, c), lambda x, g, c: _reference_chroma(x, c)),
                            (edges_loss, _reference_edges),
                            (lambda x, g, c: tv_loss(x), lambda x, g, c: _reference_tv(x))]:
        img, gt, coverage = _inputs(*size, torch.float32, seed=3)
        got = term(img, gt, cov_of(coverage))
        (grad,) = torch.autograd.grad(got, img)
        img_ref = img.detach().clone().requires_grad_(True)
        want = reference(img_ref, gt, cov_of(coverage))
        (grad_ref,) = torch.autograd.grad(want, img_ref)
        torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-7)
        torch.testing.assert_close(grad, grad_ref, rtol=1e-5, atol=1e-7)


def test_the_adjoint_of_the_differences_is_their_transpose():
    gen = torch.Generator().manual_seed(1)
    planes = torch.rand(2, 3, 5, 6, generator=gen, dtype=torch.float64)
    gx, gy = torch.rand(2, 3, 5, 5, generator=gen, dtype=torch.float64), torch.rand(2, 3, 4, 6, generator=gen,
                                                                                      dtype=torch.float64)
    dx, dy = _differences(planes)
    # <D p, g> = <p, Dᵀ g>
    torch.testing.assert_close((dx * gx).sum() + (dy * gy).sum(), (planes * adjoint_differences(gx, gy)).sum())


def test_the_terms_need_no_gradient_and_a_flat_image_has_none():
    flat = torch.full((1, 3, 4, 5), 0.4)
    with torch.no_grad():
        assert float(chroma_tv_loss(flat)) == 0.0 and float(tv_loss(flat)) == 0.0
        assert float(edges_loss(flat, flat.clone(), torch.ones(4, 5))) == 0.0
    grey = torch.rand(1, 1, 4, 5).expand(1, 3, 4, 5).clone().requires_grad_(True)  # luminance only: no chroma
    chroma_tv_loss(grey).backward()
    assert float(grey.grad.abs().max()) == 0.0
    assert SquaredVariation.apply(torch.ones(1, 3, 1, 1)) == 0.0  # one pixel: no pairs


def test_a_channels_last_render_is_summed_without_a_copy():
    render = torch.rand(9, 11, 3).permute(2, 0, 1)[None].requires_grad_(True)  # as the engine's renders arrive
    assert render.is_contiguous(memory_format=torch.channels_last) and not render.is_contiguous()
    coverage = torch.rand(9, 11)
    with load_bench("device_profile").DispatchCount() as seen:  # copies are computing operators: all counted
        tv, chroma = tv_loss(render), chroma_tv_loss(render, coverage)
    assert not [name for name in seen.names if name.startswith(("clone", "_to_copy", "copy_"))], seen.names
    torch.testing.assert_close(tv, _reference_tv(render), rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(chroma, _reference_chroma(render, coverage), rtol=1e-6, atol=1e-7)
