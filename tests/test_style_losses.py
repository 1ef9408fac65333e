"""NNFM, content, TV and the combined StyleLoss (weights, skipped terms, call counters)."""

from __future__ import annotations

import pytest
import torch

from gstyle_core.style.clip import ClipStyleLoss, ClipVisionEncoder, CoarseStyleLoss
from gstyle_core.style.features import concat_features, normalise_vectors, vector_norms
from gstyle_core.style.losses import StyleLoss, StyleWeights, content_loss, stacked_content_loss
from gstyle_core.style.nnfm import CosineDistance, StyleTarget, nnfm_loss
from gstyle_core.style.pixel_terms import tv_loss
from gstyle_core.style.vgg import VGGFeatures


def _brute_force_nnfm(render: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
    r = render.permute(0, 2, 3, 1).reshape(-1, render.shape[1]).double()
    s = style.reshape(style.shape[0], -1).t().double()
    cos = torch.nn.functional.cosine_similarity(r[:, None, :], s[None, :, :], dim=-1)
    return (1 - cos).min(dim=1).values.mean()


def test_nnfm_matches_brute_force_and_chunking():
    torch.manual_seed(0)
    render = torch.randn(1, 12, 7, 9)
    style = torch.randn(12, 5, 6)
    expected = _brute_force_nnfm(render, style)
    for chunk in (1, 5, 63, 10_000):
        torch.testing.assert_close(nnfm_loss(render, style, chunk=chunk).double(), expected, atol=1e-6, rtol=1e-6)
    target = StyleTarget.from_features(style)
    torch.testing.assert_close(nnfm_loss(render, target).double(), expected, atol=1e-6, rtol=1e-6)
    torch.testing.assert_close(nnfm_loss(render, target.matrix).double(), expected, atol=1e-6, rtol=1e-6)


def test_nnfm_is_zero_for_style_itself_and_gradient_is_render_only():
    torch.manual_seed(1)
    style = torch.randn(8, 4, 4, requires_grad=True)
    assert nnfm_loss(style.detach()[None], style).item() < 1e-6
    render = torch.randn(1, 8, 3, 3, requires_grad=True)
    loss = nnfm_loss(render, style)
    loss.backward()
    assert torch.isfinite(render.grad).all() and render.grad.abs().sum() > 0
    assert style.grad is None


def test_nnfm_zero_vectors_are_finite():
    render = torch.zeros(1, 6, 4, 4, requires_grad=True)
    style = torch.zeros(6, 3, 3)
    style[0, 0, 0] = 1.0
    loss = nnfm_loss(render, style)
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(render.grad).all()
    assert loss.item() == pytest.approx(1.0)


def test_nnfm_rejects_mismatched_channels():
    with pytest.raises(ValueError, match="do not match"):
        nnfm_loss(torch.randn(1, 5, 2, 2), torch.randn(6, 2, 2))


def test_content_and_tv_definitions():
    a = {name: torch.full((1, 2, 3, 3), 1.0) for name in ("relu3_1", "relu3_2", "relu3_3")}
    b = {name: torch.zeros(1, 2, 3, 3) for name in a}
    assert content_loss(a, b).item() == pytest.approx(3.0)  # per-layer MSE (1.0) summed over three layers
    assert content_loss(concat_features(a), concat_features(b)).item() == pytest.approx(1.0)
    img = torch.zeros(1, 3, 4, 5)
    img[..., 2] = 0.5  # one bright column: 2 vertical edges per row
    assert tv_loss(img).item() == pytest.approx(3 * 4 * 2 * 0.25)
    assert tv_loss(img, kind="abs").item() == pytest.approx(3 * 4 * 2 * 0.5)
    assert tv_loss(torch.ones(2, 3, 6, 6)).item() == 0.0
    with pytest.raises(ValueError):
        tv_loss(img, kind="l3")


class _CountingVGG(VGGFeatures):
    """Counts the network's runs: ``forward`` (the layers apart) and ``stacked`` (their stack)."""

    def __init__(self):
        super().__init__()
        self.forward_calls = 0

    def forward(self, img):
        self.forward_calls += 1
        return super().forward(img)

    def stacked(self, img):
        self.forward_calls += 1
        return super().stacked(img)


class _CountingEncoder(ClipVisionEncoder):
    pass


@pytest.fixture(scope="module")
def parts():
    torch.manual_seed(0)
    vgg = _CountingVGG()
    style = torch.rand(1, 3, 48, 48)
    target = StyleTarget.from_image(vgg, style, scales=(1.0, 0.5))
    encoder = _CountingEncoder(image_size=32, patch_size=16, width=64, layers=1, heads=1, output_dim=8)
    clip_term = ClipStyleLoss(encoder, style, n_crops=2)
    return vgg, target, clip_term, encoder


def test_style_target_scales_pool_candidates(parts):
    vgg, target, _, _ = parts
    assert target.matrix.shape == (768, 12 * 12 + 6 * 6)
    torch.testing.assert_close(target.matrix.norm(dim=0), torch.ones(180), atol=1e-4, rtol=0)


def test_combined_loss_and_zero_weight_terms_are_skipped(parts):
    vgg, target, clip_term, encoder = parts
    loss_fn = StyleLoss(vgg, target, clip_term, working_width=40)
    render = torch.rand(1, 3, 36, 48, requires_grad=True)
    gt = torch.rand(1, 3, 36, 48)

    vgg.forward_calls, encoder.calls = 0, 0
    total, terms = loss_fn(render, gt)
    total.backward()
    assert loss_fn.calls == {"vgg": 2, "clip": 1} and vgg.forward_calls == 2 and encoder.calls == 1
    assert terms.pop("multiscale") == 0.0  # weight 0 by default (the settings turn it on without CLIP weights)
    assert terms.pop("chroma_tv") == 0.0  # likewise (the settings' defaults set it)
    assert terms.pop("edges") == 0.0  # likewise
    assert all(v > 0 for v in terms.values()) and torch.isfinite(render.grad).all()
    w = StyleWeights()
    expected = w.clip * terms["clip"] + w.nnfm * terms["nnfm"] + w.content * terms["content"] + w.tv * terms["tv"]
    assert total.item() == pytest.approx(expected, rel=1e-5)

    loss_fn.weights = {"nnfm": 0.0, "content": 0.0}
    total, terms = loss_fn(render, gt)
    assert vgg.forward_calls == 2 and loss_fn.calls == {"vgg": 2, "clip": 2}
    assert terms["nnfm"] == 0.0 and terms["content"] == 0.0

    loss_fn.weights = StyleWeights(clip=0.0, nnfm=1.0, content=0.0, tv=0.0)
    total, terms = loss_fn(render)  # no gt needed without the content term
    assert encoder.calls == 2 and loss_fn.calls == {"vgg": 3, "clip": 2}
    assert total.item() == pytest.approx(terms["nnfm"], rel=1e-6) and terms["tv"] == 0.0

    loss_fn.weights = StyleWeights(clip=0.0, nnfm=0.0, content=0.0, tv=1.0)
    total, _ = loss_fn(render)
    assert loss_fn.calls == {"vgg": 3, "clip": 2}
    assert total.item() == pytest.approx(tv_loss(render).item())


def test_weight_validation(parts):
    vgg, target, _, _ = parts
    loss_fn = StyleLoss(vgg, target, None, weights=StyleWeights(clip=0.0))
    with pytest.raises(ValueError, match="CLIP"):
        loss_fn.weights = {"clip": 1.0}
    with pytest.raises(ValueError, match="unknown"):
        loss_fn.weights = {"style": 1.0}
    with pytest.raises(ValueError, match=">= 0"):
        loss_fn.weights = {"tv": -1.0}
    with pytest.raises(ValueError, match="gt"):
        loss_fn(torch.rand(1, 3, 16, 16))
    assert StyleWeights.for_scene_kind("360").nnfm == 10.0 and StyleWeights.for_scene_kind("forward").nnfm == 100.0


def test_coarse_substitute_counts_as_vgg(parts):
    vgg, target, _, _ = parts
    coarse = CoarseStyleLoss(vgg, torch.rand(1, 3, 64, 64))
    loss_fn = StyleLoss(vgg, target, coarse, weights=StyleWeights(nnfm=0.0, content=0.0, tv=0.0))
    total, terms = loss_fn(torch.rand(1, 3, 64, 64))
    assert loss_fn.calls == {"vgg": 1, "clip": 0} and terms["clip"] > 0


def test_the_edges_term_holds_luminance_edges_and_leaves_colour_free():
    """``edges_loss``: 0 for the content target itself and for any change of hue at the same luminance; positive for
    an edge moved or a new one; the scene's silhouette (coverage 0 outside) does not count; its weight at 0 skips
    it and without a content target it is refused."""
    from gstyle_core.style.pixel_terms import edges_loss, luminance

    gt = torch.zeros(1, 3, 16, 16)
    gt[..., :, 8:] = 0.8  # a vertical edge
    assert float(edges_loss(gt, gt)) == 0.0
    hue = gt.clone()
    hue[:, 0] += 0.1 * 0.587
    hue[:, 1] -= 0.1 * 0.299  # same luminance, another colour
    assert torch.allclose(luminance(hue), luminance(gt), atol=1e-6) and float(edges_loss(hue, gt)) < 1e-10
    moved = torch.zeros_like(gt)
    moved[..., :, 5:] = 0.8
    assert float(edges_loss(moved, gt)) > 0.01
    outside = gt.clone()
    outside[..., :, 12:] = 0.0  # a new edge where the scene is not
    cover = torch.ones(16, 16)
    cover[:, 12:] = 0.0
    assert float(edges_loss(outside, gt, cover)) == 0.0 < float(edges_loss(outside, gt))
    render = moved.clone().requires_grad_(True)
    loss = StyleLoss(None, None, weights={"nnfm": 0.0, "content": 0.0, "clip": 0.0, "tv": 0.0, "edges": 2.0})
    total, terms = loss(render, gt)
    total.backward()
    assert float(total.detach()) == pytest.approx(2.0 * terms["edges"]) and render.grad.abs().sum() > 0
    with pytest.raises(ValueError, match="content target"):
        loss(render)
    loss.weights = {"edges": 0.0}
    assert loss(render)[1]["edges"] == 0.0  # weight 0: not computed (no target needed)


@pytest.mark.parametrize("weighted", [False, True])
def test_the_stacked_content_loss_is_the_sum_of_the_layers_means(weighted):
    gen = torch.Generator().manual_seed(4)
    names = ("relu3_1", "relu3_2", "relu3_3")
    f64 = torch.float64  # the identity, not float32's summation order
    render = {name: torch.rand(1, 256, 9, 11, generator=gen, dtype=f64) for name in names}
    gt = {name: torch.rand(1, 256, 9, 11, generator=gen, dtype=f64) for name in names}
    grid = torch.rand(1, 1, 9, 11, generator=gen, dtype=f64) if weighted else None
    torch.testing.assert_close(stacked_content_loss(concat_features(render), concat_features(gt), grid),
                               content_loss(render, gt, weights=grid), rtol=1e-12, atol=0)


def test_the_cosine_distances_closed_form_gradient_is_autograds():
    gen = torch.Generator().manual_seed(2)
    vectors = torch.randn(30, 8, dtype=torch.float64, generator=gen).requires_grad_(True)
    matched = normalise_vectors(torch.randn(30, 8, dtype=torch.float64, generator=gen), dim=1)

    def distance(v):  # the norms as nnfm_loss gives them: of the same vectors, without a graph of their own
        return CosineDistance.apply(v, matched, vector_norms(v.detach()))

    assert torch.autograd.gradcheck(distance, (vectors,))
    through_autograd = 1.0 - (normalise_vectors(vectors, dim=1) * matched).sum(1)
    torch.testing.assert_close(distance(vectors), through_autograd)
    weights = torch.rand(30, dtype=torch.float64, generator=gen)
    expected = torch.autograd.grad((through_autograd * weights).sum(), vectors)[0]
    torch.testing.assert_close(torch.autograd.grad((distance(vectors) * weights).sum(), vectors)[0], expected)
