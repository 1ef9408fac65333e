"""CLIP encoder, loader key layouts, crop edge cases, and the coarse-VGG substitute."""

from __future__ import annotations

import math

import pytest
import torch

from gstyle_core.errors import WeightsUnavailableError
from gstyle_core.style import clip as clip_mod
from gstyle_core.style.clip import (
    COARSE_LABEL,
    ClipStyleLoss,
    ClipVisionEncoder,
    CoarseStyleLoss,
    encoder_from_state_dict,
    load_clip,
    random_square_crops,
    spherical_distance,
)
from gstyle_core.style.vgg import VGGFeatures

TINY = dict(image_size=32, patch_size=8, width=128, layers=2, heads=2, output_dim=16)  # 64-wide heads, as CLIP


def _tiny_encoder(seed: int = 0) -> ClipVisionEncoder:
    torch.manual_seed(seed)
    return ClipVisionEncoder(**TINY).eval()


def test_tiny_vit_loss_is_finite_with_gradients():
    encoder = _tiny_encoder()
    style = torch.rand(1, 3, 50, 70)
    loss_fn = ClipStyleLoss(encoder, style, n_crops=4, generator=torch.Generator().manual_seed(0))
    render = torch.rand(1, 3, 40, 60, requires_grad=True)
    loss = loss_fn(render)
    loss.backward()
    assert loss.ndim == 0 and torch.isfinite(loss) and loss > 0
    assert render.grad is not None and torch.isfinite(render.grad).all() and render.grad.abs().sum() > 0
    assert all(p.grad is None for p in encoder.parameters())
    assert encoder.calls == 2  # one for the style embedding, one for the batch of crops


def test_same_image_has_near_zero_distance():
    encoder = _tiny_encoder()
    style = torch.rand(1, 3, 32, 32)
    loss_fn = ClipStyleLoss(encoder, style, n_crops=3)
    # Crops of a 32-px image with 32-px input size are the whole image: distance to itself is 0.
    assert loss_fn(style).item() < 1e-6


def test_spherical_distance_values():
    a = torch.tensor([[1.0, 0.0], [0.0, 2.0], [-1.0, 0.0]])
    b = torch.tensor([[3.0, 0.0]])
    d = spherical_distance(a, b)
    # 2·arcsin(chord/2)² = θ²/2 for the angle θ between the vectors.
    torch.testing.assert_close(d, torch.tensor([0.0, (math.pi / 2) ** 2 / 2, math.pi ** 2 / 2]))


@pytest.mark.parametrize("shape", [(1, 1), (3, 200), (200, 3), (7, 7)])
def test_crops_of_tiny_and_thin_images(shape):
    img = torch.rand(1, 3, *shape, requires_grad=True)
    crops = random_square_crops(img, n_crops=5, out_size=24, generator=torch.Generator().manual_seed(1))
    assert crops.shape == (5, 3, 24, 24) and torch.isfinite(crops).all()
    crops.sum().backward()
    assert torch.isfinite(img.grad).all()
    loss = ClipStyleLoss(_tiny_encoder(), torch.rand(1, 3, 1, 1), n_crops=2)(img.detach())
    assert torch.isfinite(loss)


def test_crop_sides_follow_the_reference_range():
    img = torch.arange(100 * 300, dtype=torch.float32).view(1, 1, 100, 300).expand(1, 3, 100, 300)
    gen = torch.Generator().manual_seed(0)
    for _ in range(20):
        crop = random_square_crops(img, 1, out_size=100, generator=gen)
        assert crop.shape[-1] == 100  # short side 100 ≤ out_size: the crop is the full short side


def _openai_style_dict(encoder: ClipVisionEncoder) -> dict[str, torch.Tensor]:
    state = {f"visual.{k}": v.clone() for k, v in encoder.state_dict().items()}
    state["token_embedding.weight"] = torch.zeros(10, 4)  # text tower keys are ignored
    state["logit_scale"] = torch.tensor(4.6)
    return state


def test_loader_maps_openai_and_openclip_layouts(tmp_path, monkeypatch):
    encoder = _tiny_encoder(3)
    x = torch.rand(2, 3, 32, 32)
    with torch.no_grad():
        expected = encoder(x)
    openai = tmp_path / "ViT-B-32.pt"
    torch.save(_openai_style_dict(encoder), openai)
    openclip = tmp_path / "open_clip_pytorch_model.bin"
    torch.save({"state_dict": {f"module.{k}": v for k, v in _openai_style_dict(encoder).items()}}, openclip)
    for file in (openai, openclip):
        loaded, message = load_clip(file)
        assert loaded is not None and str(file) in message
        assert (loaded.image_size, loaded.conv1.kernel_size[0], len(loaded.transformer.resblocks)) == (32, 8, 2)
        with torch.no_grad():
            torch.testing.assert_close(loaded(x), expected)
    monkeypatch.setenv(clip_mod.CLIP_ENV, str(openclip))
    assert load_clip()[0] is not None


def test_jit_archive_is_read(tmp_path):
    encoder = _tiny_encoder(4)

    class Holder(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.visual = encoder

        def forward(self, x):
            return self.visual(x)

    scripted = torch.jit.trace(Holder(), torch.rand(1, 3, 32, 32), check_trace=False)
    path = tmp_path / "ViT-B-32.pt"
    scripted.save(str(path))
    loaded, _ = load_clip(path)
    torch.testing.assert_close(loaded.proj, encoder.proj)


def test_absent_weights_give_reason(tmp_path, monkeypatch):
    monkeypatch.delenv(clip_mod.CLIP_ENV, raising=False)
    monkeypatch.setattr(clip_mod, "clip_search_paths", lambda: [tmp_path / "nothing" / "ViT-B-32.pt"])
    encoder, reason = load_clip()
    assert encoder is None and "\n" not in reason and "not found" in reason and COARSE_LABEL in reason
    with pytest.raises(WeightsUnavailableError, match="does not exist"):
        load_clip(tmp_path / "missing.pt")
    bad = tmp_path / "bad.pt"
    torch.save({"visual.conv1.weight": torch.zeros(4, 3, 2, 2)}, bad)
    with pytest.raises(WeightsUnavailableError, match="not a CLIP"):
        load_clip(bad)


def test_shape_mismatch_is_one_line_error():
    state = _openai_style_dict(_tiny_encoder())
    state["visual.ln_post.weight"] = torch.ones(3)
    with pytest.raises(WeightsUnavailableError) as info:
        encoder_from_state_dict(state)
    assert "\n" not in str(info.value)


def test_coarse_substitute_is_finite_and_differentiable():
    torch.manual_seed(0)
    vgg = VGGFeatures()
    style = torch.rand(1, 3, 64, 96)
    coarse = CoarseStyleLoss(vgg, style)
    assert coarse.label == COARSE_LABEL and coarse.network == "vgg"
    render = torch.rand(1, 3, 3, 200, requires_grad=True)
    loss = coarse(render)
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(render.grad).all()
    assert coarse(style).item() < 1e-8  # the style image matches its own statistics


@pytest.mark.parametrize("mixed", [False, True], ids=["one painting", "a mix"])
@pytest.mark.parametrize("covered", [False, True], ids=["whole frames", "coverage"])
def test_the_coarse_substitute_gives_each_render_of_a_batch_its_value_alone(mixed, covered):
    torch.manual_seed(0)
    vgg = VGGFeatures()
    gen = torch.Generator().manual_seed(3)
    styles = [torch.rand(1, 3, 64, 96, generator=gen), torch.rand(1, 3, 80, 64, generator=gen)]
    coarse = CoarseStyleLoss(vgg, styles if mixed else styles[0], style_weights=(0.3, 0.7) if mixed else None)
    renders = torch.rand(3, 3, 72, 100, generator=gen)
    coverage = (torch.rand(3, 72, 100, generator=gen) > 0.4).float() if covered else None
    if covered:
        coverage[1] = 0.0  # a view without the scene: every position weighs alike, as alone
    alone = torch.stack([coarse(renders[i:i + 1], None if coverage is None else coverage[i]) for i in range(3)])
    per_image = coarse.per_image(renders, coverage)
    assert per_image.shape == (3,) and len(set(per_image.tolist())) == 3
    torch.testing.assert_close(per_image, alone, rtol=1e-5, atol=1e-7)
    torch.testing.assert_close(coarse(renders, None if coverage is None else coverage[:, None]), alone.mean(),
                               rtol=1e-5, atol=1e-7)
