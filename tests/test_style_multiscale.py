"""The multi-scale style term: NNFM of render and painting downsampled ×2, ×4 and ×8."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from gstyle_core.style.features import concat_features
from gstyle_core.style.multiscale import MultiScaleStyleLoss, downsample
from gstyle_core.style.nnfm import StyleTarget, nnfm_loss
from gstyle_core.style.texture_scale import band_shares


def _painting(h: int = 64, w: int = 96, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.rand(1, 3, h, w, generator=g)


def test_zero_for_the_painting_itself_and_positive_otherwise(vgg):
    painting = _painting()
    term = MultiScaleStyleLoss(vgg, painting)
    assert float(term(painting)) == pytest.approx(0.0, abs=1e-5)
    assert set(term.last_levels) == {2.0, 4.0, 8.0}
    assert float(term(_painting(seed=1))) > 1e-3


def test_with_factors_is_the_same_term_at_other_levels(vgg):
    a, b = _painting(), _painting(seed=7)
    render = _painting(48, 80, seed=8)
    term = MultiScaleStyleLoss(vgg, [a, b], style_weights=(0.25, 0.75))
    term.set_style_weights((0.6, 0.4))  # a mix re-weighted after it was built
    other = term.with_factors((2, 4))
    assert other.factors == (2.0, 4.0)
    fresh = MultiScaleStyleLoss(vgg, [a, b], factors=(2, 4), style_weights=(0.6, 0.4))
    torch.testing.assert_close(other(render), fresh(render))
    assert float(other(render)) != pytest.approx(float(term(render)), abs=1e-6)


def test_each_level_is_nnfm_on_downsampled_images(vgg):
    painting, render = _painting(), _painting(48, 80, seed=3)
    term = MultiScaleStyleLoss(vgg, painting, factors=(4,))
    target = StyleTarget.from_image(vgg, downsample(painting, 4))
    expected = nnfm_loss(concat_features(vgg(downsample(render, 4))), target)
    torch.testing.assert_close(term(render), expected)


def test_its_gradient_is_coarse(vgg):
    painting, render = _painting(), _painting(seed=4).requires_grad_(True)
    fine_term = MultiScaleStyleLoss(vgg, painting, factors=(1,))
    coarse_term = MultiScaleStyleLoss(vgg, painting, factors=(4,))
    shares = []
    for term in (fine_term, coarse_term):
        render.grad = None
        term(render).backward()
        shares.append(band_shares(render.grad[0].permute(1, 2, 0).numpy()))
    assert shares[1][0] < 0.5 * shares[0][0]  # far less of its gradient at the pixel scale
    assert shares[1][2] > 2 * shares[0][2]


def test_coverage_weights_the_scene(vgg):
    painting, render = _painting(), _painting(seed=5)
    term = MultiScaleStyleLoss(vgg, painting)
    full = term(render, torch.ones(64, 96))
    torch.testing.assert_close(full, term(render))
    assert float(term(render, torch.zeros(64, 96))) == 0.0  # nothing of the scene in view: nothing to match
    half = torch.zeros(64, 96)
    half[:, :48] = 1.0
    assert float(term(render, half)) != pytest.approx(float(full), abs=1e-6)


def test_small_renders_mixes_and_bad_arguments(vgg):
    a, b = _painting(), _painting(seed=6)
    render = _painting(10, 12, seed=7)
    assert np.isfinite(float(MultiScaleStyleLoss(vgg, a)(render)))  # ×4 of 10 px is stretched to VGG's minimum
    mixed = MultiScaleStyleLoss(vgg, [a, b], style_weights=(1.0, 0.0))
    torch.testing.assert_close(mixed(render), MultiScaleStyleLoss(vgg, a)(render))
    mixed.set_style_weights((0.0, 1.0))
    torch.testing.assert_close(mixed(render), MultiScaleStyleLoss(vgg, b)(render))
    with pytest.raises(ValueError):
        MultiScaleStyleLoss(vgg, a, factors=(0.5,))
    with pytest.raises(ValueError):
        MultiScaleStyleLoss(vgg, [a, b], style_weights=(1.0,))
    with pytest.raises(ValueError):
        MultiScaleStyleLoss(vgg, [])
    with pytest.raises(ValueError):
        MultiScaleStyleLoss(vgg, a)(render[0])


def test_the_combined_loss_adds_it_only_when_weighted(vgg):
    """In ``StyleLoss`` the term is λ_MS × the term on the same render, counted as one VGG run per level; at weight 0
    it never runs and the total is the four-term sum; a weight without the term is refused."""
    from gstyle_core.style.losses import StyleLoss, StyleWeights
    from gstyle_core.style.nnfm import StyleTarget

    painting = _painting()
    term = MultiScaleStyleLoss(vgg, painting)
    target = StyleTarget.from_image(vgg, painting)
    render = _painting(seed=3).requires_grad_(True)
    off = StyleLoss(vgg, target, None, weights=StyleWeights(clip=0.0, tv=0.0), multiscale_term=term)
    on = StyleLoss(vgg, target, None, weights=StyleWeights(clip=0.0, tv=0.0, multiscale=7.0), multiscale_term=term)
    total_off, terms_off = off(render, render.detach())
    total_on, terms_on = on(render, render.detach())
    assert terms_off["multiscale"] == 0.0 and off.calls["vgg"] == 2  # render + content features
    assert on.calls["vgg"] == 2 + len(term.factors)
    assert terms_on["multiscale"] == pytest.approx(float(term(render.detach())), rel=1e-6)
    assert float((total_on - total_off).detach()) == pytest.approx(7.0 * terms_on["multiscale"], rel=1e-4)
    with pytest.raises(ValueError, match="broad-strokes"):
        StyleLoss(vgg, target, None, weights=StyleWeights(clip=0.0, multiscale=1.0))


@pytest.mark.parametrize("mixed", [False, True], ids=["one painting", "a mix"])
@pytest.mark.parametrize("covered", [False, True], ids=["whole frames", "coverage"])
def test_a_batch_gives_each_render_the_value_it_has_alone(vgg, mixed, covered):
    paintings = [_painting(seed=1), _painting(48, 64, seed=2)] if mixed else _painting(seed=1)
    term = MultiScaleStyleLoss(vgg, paintings, style_weights=(0.3, 0.7) if mixed else None)
    gen = torch.Generator().manual_seed(5)
    renders = torch.rand(3, 3, 40, 56, generator=gen)
    coverage = torch.rand(3, 40, 56, generator=gen) if covered else None
    coverage = None if coverage is None else coverage * (coverage > 0.3)
    alone = torch.stack([term(renders[i:i + 1], None if coverage is None else coverage[i]) for i in range(3)])
    torch.testing.assert_close(term.per_image(renders, coverage), alone, rtol=1e-5, atol=1e-6)
