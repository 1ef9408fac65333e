"""Style side on hard inputs (issue #7, section 2): colour matching with degenerate statistics, NNFM/content/TV on
zero features, VGG in bfloat16 vs float32, CLIP on degenerate crops and tiny renders, and a long stylization run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from hypothesis import given
from hypothesis import strategies as st
from torch import nn

from gstyle_core.engine.objective import StyleObjective
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.errors import WeightsUnavailableError
from gstyle_core.style.clip import (
    ClipStyleLoss,
    ClipVisionEncoder,
    CoarseStyleLoss,
    random_square_crops,
    spherical_distance,
)
from gstyle_core.style.colour_match import (
    apply_colour_transform,
    colour_statistics,
    colour_transfer_matrix,
    match_colours,
)
from gstyle_core.style.losses import StyleLoss, StyleWeights, content_loss
from gstyle_core.style.nnfm import StyleTarget, nnfm_loss
from gstyle_core.style.pixel_terms import tv_loss
from gstyle_core.style.vgg import VGGFeatures, load_vgg
from tests.synthetic import blob_scene, ring_cameras
from tests.test_stability_raster import fuzz_settings

# bfloat16 vs float32 VGG: bf16 keeps 8 significant bits (relative rounding 2^-9 ~ 2e-3 per operation). The loss
# terms are means over thousands of features, so rounding partly averages out. Measured on 6 image triples of
# these sizes, both weight kinds: worst term 5.4e-3 relative (coarse-VGG, random weights), NNFM <= 4.8e-4,
# content <= 1.2e-3, total <= 4.1e-4. Render gradients do not average out per pixel, so their direction is
# compared: cosine >= 0.9837 (random weights), >= 0.9980 (ImageNet weights).
BF16_LOSS_RTOL = 1e-2
BF16_GRAD_COSINE = 0.97


def _rng_colours(seed: int, n: int = 600) -> np.ndarray:
    return np.random.default_rng(seed).uniform(size=(n, 3))


# ------------------------------------------------------------------------------------------- colour matching

@pytest.mark.parametrize("content_kind", ["colourful", "ill_conditioned", "one_colour"])
def test_uniform_style_turns_every_pixel_into_the_style_colour(content_kind):
    content = _rng_colours(0)
    if content_kind == "ill_conditioned":
        content = np.repeat(content[:, :1], 3, axis=1) + 1e-3 * content
    elif content_kind == "one_colour":
        content = np.full((600, 3), 0.4)
    colour = np.array([0.9, 0.2, 0.05])
    out = match_colours(content, np.tile(colour, (50, 1)), clip=False)
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out, np.broadcast_to(colour, out.shape), atol=1e-3)  # every pixel, not the mean


def test_greyscale_style_gives_grey_output_with_the_style_levels():
    style = np.repeat(np.random.default_rng(1).beta(2, 5, size=(400, 1)), 3, axis=1)  # grey, skewed levels
    content = _rng_colours(2) * [1.0, 0.3, 0.6] + [0.0, 0.5, 0.1]  # colourful
    out = match_colours(content, style, clip=False).astype(np.float64)
    assert np.abs(out[:, 0] - out[:, 1]).max() <= 1e-3 and np.abs(out[:, 1] - out[:, 2]).max() <= 1e-3
    mean_o, cov_o = colour_statistics(out)
    mean_s, cov_s = colour_statistics(style)
    np.testing.assert_allclose(mean_o, mean_s, atol=1e-6)
    np.testing.assert_allclose(cov_o, cov_s, atol=1e-6)  # grey levels spread like the style's


def test_one_colour_scene_maps_to_the_style_mean():
    style = _rng_colours(3, 300) * [0.5, 1.0, 0.2]
    exact = match_colours(np.full((40, 3), 0.25), style, clip=False)
    np.testing.assert_allclose(exact, np.broadcast_to(style.mean(0), exact.shape), atol=1e-6)
    # Numerical noise (1e-7) is amplified at most 1e4 times: still within 1e-3 of the style mean.
    noisy = np.full((40, 3), 0.25) + np.random.default_rng(4).normal(scale=1e-7, size=(40, 3))
    out = match_colours(noisy, style, clip=False)
    assert np.abs(out - style.mean(0)).max() <= 1e-3


@pytest.mark.parametrize("factor", [1e-3, 1e4, 1e6, 1e9])
def test_content_scale_does_not_change_the_result(factor):
    """Regression: eigenvalues were also clamped at 1e8, so content with values ~1e6 was mapped 30x too wide."""
    content, style = _rng_colours(5), _rng_colours(6, 300)
    reference = match_colours(content, style, clip=False)
    scaled = match_colours(content * factor, style, clip=False)
    np.testing.assert_allclose(scaled, reference, atol=1e-5)


@pytest.mark.parametrize("case", ["dark_style_few_highlights", "correlated_content", "huge_style_range"])
def test_ill_conditioned_covariances_are_matched_exactly(case):
    rng = np.random.default_rng(7)
    content, style = _rng_colours(8), _rng_colours(9, 500)
    if case == "dark_style_few_highlights":
        style = 0.01 * style
        style[:3] = [[1.0, 0.9, 0.2], [0.9, 1.0, 0.3], [1.0, 1.0, 0.25]]
    elif case == "correlated_content":  # condition number ~ 1e5, all spreads above the 1e-4 noise floor
        content = np.repeat(content[:, :1], 3, axis=1) + 3e-3 * rng.normal(size=(600, 3))
    else:
        style = style * 1e6
    transform, offset = colour_transfer_matrix(content, style)
    mapped = apply_colour_transform(content, transform, offset, clip=False).astype(np.float64)
    mean_m, cov_m = colour_statistics(mapped)
    mean_s, cov_s = colour_statistics(style)
    scale = np.abs(cov_s).max()
    np.testing.assert_allclose(mean_m, mean_s, atol=1e-5 * np.abs(mean_s).max())
    np.testing.assert_allclose(cov_m / scale, cov_s / scale, atol=1e-4)
    clipped = apply_colour_transform(content, transform, offset)
    assert clipped.min() >= 0 and clipped.max() <= 1


def test_values_beyond_float64_covariance_range_are_a_clear_error():
    with pytest.raises(ValueError, match="exceed") as info:
        colour_transfer_matrix(_rng_colours(1) * 1e200, _rng_colours(2))
    assert "\n" not in str(info.value)


@st.composite
def degenerate_pixels(draw):
    """Colours mean + noise @ mix with per-axis spreads from exactly 0 to 1e3 (rank 0-3, any conditioning)."""
    n = draw(st.integers(1, 40))
    spreads = [draw(st.one_of(st.just(0.0), st.floats(-9, 3).map(lambda e: 10.0**e))) for _ in range(3)]
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    mix = np.linalg.qr(rng.normal(size=(3, 3)))[0] * spreads
    return rng.uniform(size=3) + rng.normal(size=(n, 3)) @ mix.T


@fuzz_settings(40)
@given(degenerate_pixels(), degenerate_pixels())
def test_degenerate_statistics_give_finite_output_with_the_style_mean(content, style):
    transform, offset = colour_transfer_matrix(content, style)
    assert np.isfinite(transform).all() and np.isfinite(offset).all()
    out = apply_colour_transform(content, transform, offset, clip=False).astype(np.float64)
    assert np.isfinite(out).all()
    # b = mu_s - A mu_c puts the mean on the style's for any A, however degenerate the covariances.
    np.testing.assert_allclose(out.mean(0), style.mean(0), atol=1e-5 * (1 + np.abs(out).max()))
    clipped = apply_colour_transform(content, transform, offset)
    assert clipped.min() >= 0 and clipped.max() <= 1


# -------------------------------------------------------------------------------------- NNFM, content, TV

def test_nnfm_with_zero_vectors_on_both_sides_is_finite():
    render = torch.rand(1, 6, 5, 5)
    render[..., :2, :] = 0.0  # some render positions have all-zero features (e.g. ReLU of a black region)
    render.requires_grad_(True)
    style = torch.rand(6, 4, 4)
    style[:, :2] = 0.0  # zero style candidates
    loss = nnfm_loss(render, style)
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(render.grad).all()
    per_vector = nnfm_loss(render.detach(), style, reduction="none")
    assert torch.allclose(per_vector[..., :2, :], torch.ones(1, 2, 5))  # cosine of zero is 0: distance 1
    all_zero = torch.zeros(1, 6, 3, 3, requires_grad=True)
    loss = nnfm_loss(all_zero, torch.zeros(6, 2, 2))
    loss.backward()
    assert loss.item() == pytest.approx(1.0) and torch.isfinite(all_zero.grad).all()


def test_nnfm_rejects_empty_render_features():
    with pytest.raises(ValueError, match="no feature vectors"):
        nnfm_loss(torch.zeros(1, 6, 0, 4), torch.rand(6, 2, 2))


@pytest.fixture(scope="module")
def random_vgg() -> VGGFeatures:
    torch.manual_seed(0)
    return VGGFeatures()


@pytest.mark.parametrize("colour", [0.0, 1.0])
def test_full_loss_on_flat_images_is_finite(random_vgg, colour):
    """Black or white render and style: ReLU features may vanish, std statistics are 0, TV is 0."""
    flat = torch.full((1, 3, 20, 24), colour)
    target = StyleTarget.from_image(random_vgg, flat)
    loss_fn = StyleLoss(random_vgg, target, CoarseStyleLoss(random_vgg, flat))
    render = flat.clone().requires_grad_(True)
    total, terms = loss_fn(render, flat)
    total.backward()
    assert math.isfinite(total.item()) and all(math.isfinite(v) for v in terms.values())
    assert torch.isfinite(render.grad).all()
    assert terms["tv"] == 0.0 and terms["content"] == 0.0


@pytest.mark.parametrize("shape", [(1, 1), (3, 40), (2, 64), (40, 1)])
def test_renders_below_vgg_size_are_stretched_not_crashing(random_vgg, shape):
    """Regression: a render under 4 px on a side had no relu3 features and VGG's pooling raised."""
    style = torch.rand(1, 3, 16, 16)
    loss_fn = StyleLoss(random_vgg, StyleTarget.from_image(random_vgg, style), CoarseStyleLoss(random_vgg, style))
    render = torch.rand(1, 3, *shape, requires_grad=True)
    total, terms = loss_fn(render, torch.rand(1, 3, *shape))
    total.backward()
    assert all(math.isfinite(v) for v in terms.values()) and terms["nnfm"] > 0
    assert torch.isfinite(render.grad).all() and render.grad.abs().sum() > 0


def test_content_and_tv_on_extreme_images():
    zeros = {k: torch.zeros(1, 4, 2, 2, requires_grad=True) for k in ("relu3_1", "relu3_2", "relu3_3")}
    value = content_loss(zeros, {k: torch.zeros(1, 4, 2, 2) for k in zeros})
    value.backward()
    assert value.item() == 0.0 and all(torch.isfinite(t.grad).all() for t in zeros.values())
    flat = torch.full((1, 3, 5, 5), 0.3, requires_grad=True)
    tv_loss(flat).backward()
    assert (flat.grad == 0).all()
    spiky = torch.zeros(1, 3, 6, 6)
    spiky[..., ::2, ::2] = 1.0  # maximal variation inside [0, 1]
    assert torch.isfinite(tv_loss(spiky)) and tv_loss(spiky).item() <= 3 * 2 * 6 * 5  # each difference <= 1


# -------------------------------------------------------------------------------------------- bf16 vs fp32

def _painting(h: int, w: int, seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    smooth = F.interpolate(torch.rand(1, 3, h // 8, w // 8, generator=g), size=(h, w), mode="bilinear",
                           align_corners=False)
    return (0.7 * smooth + 0.3 * torch.rand(1, 3, h, w, generator=g)).clamp(0, 1)


def _vgg_pair(kind: str) -> tuple[VGGFeatures, VGGFeatures]:
    if kind == "imagenet":
        try:
            fp32 = load_vgg()
        except WeightsUnavailableError as exc:
            pytest.skip(f"VGG-16 weights unavailable: {exc}")
    else:
        torch.manual_seed(0)
        fp32 = VGGFeatures()
    bf16 = VGGFeatures(fp32.convention)
    bf16.load_state_dict(fp32.state_dict())
    return fp32, bf16.set_compute_mode(torch.bfloat16, channels_last=True)


@pytest.mark.parametrize("kind", ["random", "imagenet"])
def test_bf16_losses_agree_with_fp32(kind):
    """Each precision end to end as the pipeline runs it (style target and coarse statistics from its own VGG; with
    ImageNet weights the NNFM search in bf16 too, as ``--precision bf16`` runs it). Random weights make features that
    all point alike, so a bf16 search (3 significant digits) flips close calls there that real features do not have
    (measured over 6 image triples: gradient cosine 0.89-0.95, NNFM up to 1.0e-2 relative; with ImageNet weights
    0.995-0.999 and <= 2.6e-4): with random weights the search stays fp32 and the network's rounding is compared."""
    style, render, gt = _painting(48, 48, 1), _painting(40, 40, 10), _painting(40, 40, 20)
    results = {}
    for name, vgg in zip(("fp32", "bf16"), _vgg_pair(kind), strict=True):
        target = StyleTarget.from_image(vgg, style)
        if kind == "random":
            target = StyleTarget(target.matrix)  # an fp32 search
        loss_fn = StyleLoss(vgg, target, CoarseStyleLoss(vgg, style), weights=StyleWeights(tv=0.0))
        leaf = render.clone().requires_grad_(True)
        total, terms = loss_fn(leaf, gt)
        total.backward()
        results[name] = (total.item(), terms, leaf.grad.flatten())
    (t32, terms32, g32), (t16, terms16, g16) = results["fp32"], results["bf16"]
    assert math.isfinite(t16) and torch.isfinite(g16).all()
    assert abs(t16 - t32) <= BF16_LOSS_RTOL * abs(t32)
    for term in ("clip", "nnfm", "content"):
        assert terms32[term] > 0
        assert abs(terms16[term] - terms32[term]) <= BF16_LOSS_RTOL * terms32[term], term
    assert float(F.cosine_similarity(g16, g32, dim=0)) >= BF16_GRAD_COSINE


# ------------------------------------------------------------------------------------------------------ CLIP

def _tiny_encoder() -> ClipVisionEncoder:  # the tiny ViT of tests/test_style_clip.py
    torch.manual_seed(0)
    return ClipVisionEncoder(image_size=32, patch_size=8, width=128, layers=2, heads=2, output_dim=16).eval()


def test_spherical_distance_at_opposite_and_equal_embeddings():
    """Regression: arcsin's infinite slope at opposite embeddings gave NaN gradients."""
    a = torch.tensor([[1.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 0.0]], requires_grad=True)
    b = torch.tensor([[0.0, -2.0, 0.0]])
    d = spherical_distance(a, b)
    d.sum().backward()
    torch.testing.assert_close(d, torch.tensor([(math.pi / 2) ** 2 / 2, math.pi**2 / 2, (math.pi / 2) ** 2 / 2]))
    assert torch.isfinite(a.grad).all()
    same = torch.tensor([[0.5, -1.0, 2.0]], requires_grad=True)
    d = spherical_distance(same, same.detach() * 7)
    d.sum().backward()
    assert abs(d.item()) <= 1e-12 and torch.isfinite(same.grad).all()


@fuzz_settings(30)
@given(st.integers(1, 40), st.integers(1, 40), st.integers(1, 40), st.integers(1, 3), st.integers(0, 2**31 - 1))
def test_random_crops_of_any_image_size_are_finite_and_bounded(height, width, out_size, n_crops, seed):
    img = (torch.rand(1, 3, height, width, generator=torch.Generator().manual_seed(seed)) * 2 - 0.5)
    img.requires_grad_(True)
    crops = random_square_crops(img, n_crops, out_size, generator=torch.Generator().manual_seed(seed))
    assert crops.shape == (n_crops, 3, out_size, out_size) and torch.isfinite(crops).all()
    lo, hi = float(img.detach().min()), float(img.detach().max())
    assert lo - 1e-6 <= float(crops.detach().min()) and float(crops.detach().max()) <= hi + 1e-6  # pixel averages
    crops.sum().backward()
    assert torch.isfinite(img.grad).all() and img.grad.sum().item() == pytest.approx(n_crops * 3 * out_size**2,
                                                                                     rel=1e-4)


@pytest.mark.parametrize("render_kind", ["one_pixel", "one_row", "one_column", "black", "white", "the_style"])
def test_clip_loss_on_degenerate_renders_is_finite(render_kind):
    style = _painting(40, 40, 3)
    loss_fn = ClipStyleLoss(_tiny_encoder(), style, n_crops=3, generator=torch.Generator().manual_seed(0))
    render = {"one_pixel": torch.rand(1, 3, 1, 1), "one_row": torch.rand(1, 3, 1, 50),
              "one_column": torch.rand(1, 3, 50, 1), "black": torch.zeros(1, 3, 30, 30),
              "white": torch.ones(1, 3, 30, 30), "the_style": style.clone()}[render_kind].requires_grad_(True)
    loss = loss_fn(render)
    loss.backward()
    assert torch.isfinite(loss) and 0.0 <= loss.item() <= math.pi**2 / 2 + 1e-6
    assert torch.isfinite(render.grad).all()


@pytest.mark.parametrize("shape", [(0, 5), (5, 0), (0, 0)])
def test_empty_images_are_a_clear_error(shape):
    """Regression: an empty style image raised ZeroDivisionError, an empty coarse render a pooling error."""
    empty = torch.rand(1, 3, *shape)
    cases = [lambda: ClipStyleLoss(_tiny_encoder(), empty, n_crops=1),
             lambda: ClipStyleLoss(_tiny_encoder(), torch.rand(1, 3, 8, 8), n_crops=1)(empty),
             lambda: CoarseStyleLoss(VGGFeatures(), empty),
             lambda: CoarseStyleLoss(VGGFeatures(), torch.rand(1, 3, 8, 8))(empty)]
    for case in cases:
        with pytest.raises(ValueError, match="empty") as info:
            case()
        assert "\n" not in str(info.value)


# -------------------------------------------------------------------------------------------------- long run

class _MiniVGG(nn.Module):
    """A VGG-shaped random feature net (3x3 conv + ReLU, two 2x max-pools, three relu3_x outputs of 16 channels):
    the real loss code (NNFM, content, coarse-VGG, TV) at a small fraction of VGG-16's cost per step."""

    def __init__(self) -> None:
        super().__init__()
        torch.manual_seed(0)
        self.stem = nn.Sequential(nn.Conv2d(3, 8, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2),
                                  nn.Conv2d(8, 16, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2))
        self.convs = nn.ModuleList(nn.Conv2d(16, 16, 3, padding=1) for _ in range(3))
        self.requires_grad_(False)

    def forward(self, img: torch.Tensor) -> dict[str, torch.Tensor]:
        x = self.stem((img - 0.45) / 0.25)
        out = {}
        for name, conv in zip(("relu3_1", "relu3_2", "relu3_3"), self.convs, strict=True):
            x = torch.relu(conv(x))
            out[name] = x
        return out


class _RecordingObjective(StyleObjective):
    """The engine's real objective on the mini net; records the range of every render it is given."""

    def __init__(self, style, settings) -> None:
        super().__init__(style, settings, vgg=_MiniVGG())
        self.render_min, self.render_max, self.render_finite, self.renders = math.inf, -math.inf, True, 0

    def evaluate(self, image, content, view, coverage=None, together=None):  # what the engine's steps call
        self.renders += 1
        self.render_finite &= bool(torch.isfinite(image).all())
        self.render_min = min(self.render_min, float(image.detach().min()))
        self.render_max = max(self.render_max, float(image.detach().max()))
        return super().evaluate(image, content, view, coverage, together=together)


@pytest.mark.slow
def test_long_stylization_run_stays_in_range_and_does_not_diverge():
    """3,000 Adam steps of the real Stylizer (preview weights, coarse-VGG term, a split and refit) at 32 px.
    Measured: last-100 mean / steps 200-300 mean = 0.964, largest step loss after warm-up = the warm-up window max."""
    steps = 3000
    style = _painting(64, 64, 5)[0].permute(1, 2, 0).numpy()
    settings = resolve_settings("preview", "forward", 2, max_views=2, epochs=1.0, min_steps=steps, working_width=32,
                                preprocess_rounds=0, refit_iterations=10, split_at=(), max_gaussians=5000)
    engine = Stylizer(blob_scene(200, seed=3), ring_cameras(2), style, settings, objective_factory=_RecordingObjective)
    totals = []
    while not engine.done:
        report = engine.step()
        assert all(math.isfinite(v) for v in report.losses.values()), report
        if report.phase == "stylize" and "total" in report.losses:
            totals.append(report.losses["total"])
            if len(totals) % 100 == 0:
                colours = engine.c_s.detach()
                assert torch.isfinite(colours).all() and colours.min() >= 0 and colours.max() <= 1
    assert len(totals) >= steps - 1
    objective = engine.objective
    assert objective.renders >= steps - 1  # every step's render was seen
    assert objective.render_finite and objective.render_min >= 0.0 and objective.render_max <= 1.0 + 1e-5
    final = engine.c_s
    assert torch.isfinite(final).all() and final.min() >= 0 and final.max() <= 1
    totals = np.array(totals)
    warm, last = totals[200:300].mean(), totals[-100:].mean()  # equal numbers of both views in each window
    assert last <= 1.05 * warm, (warm, last)
    assert totals[200:].max() <= 1.5 * totals[200:300].max()  # no spike after warm-up
