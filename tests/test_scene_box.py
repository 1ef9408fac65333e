"""The networks look only at the box a rendered view's scene covers: same losses, fewer pixels."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from gstyle_core.engine.objective import StyleObjective
from gstyle_core.engine.scene_box import SCENE_BOX_ALIGN_PX, SCENE_BOX_MARGIN_PX, box_fraction, scene_box
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.style.losses import StyleWeights


def _object_view(h: int = 96, w: int = 160, top: int = 30, left: int = 60, size: int = 36, seed: int = 0):
    """A textured square 'object' on a black background: render, content, coverage."""
    g = torch.Generator().manual_seed(seed)
    coverage = torch.zeros(h, w)
    coverage[top:top + size, left:left + size] = 1.0
    coverage[top - 1, left:left + size] = 0.3  # a soft edge
    render = torch.rand(h, w, 3, generator=g) * coverage[..., None]
    content = torch.rand(h, w, 3, generator=g) * coverage[..., None]
    return render, content, coverage


def test_box_holds_every_covered_pixel_plus_the_margin_on_the_aligned_grid():
    _, _, cov = _object_view()
    rows, cols = scene_box(cov)
    assert rows.start % SCENE_BOX_ALIGN_PX == 0 and cols.start % SCENE_BOX_ALIGN_PX == 0
    assert rows.start <= 29 - SCENE_BOX_MARGIN_PX and rows.stop >= 66 + SCENE_BOX_MARGIN_PX
    assert cols.start <= 60 - SCENE_BOX_MARGIN_PX and cols.stop >= 96 + SCENE_BOX_MARGIN_PX
    assert (rows.stop - rows.start) % SCENE_BOX_ALIGN_PX == 0 or rows.stop == 96
    assert float(cov[rows, cols].sum()) == pytest.approx(float(cov.sum()))
    assert 0 < box_fraction((rows, cols), 96, 160) < 0.5
    assert scene_box(torch.ones(40, 50)) is None  # the scene fills the frame: nothing to save
    assert scene_box(torch.zeros(40, 50)) is None  # nothing covered: keep the frame
    assert scene_box(torch.full((40, 50), 0.5 / 255)) is None  # below the blending cut-off counts as empty
    with pytest.raises(ValueError, match="H, W"):
        scene_box(torch.ones(1, 40, 50))


class _SizeRecorder(nn.Module):
    """Wraps a VGG and records the pixel count of every input."""

    def __init__(self, vgg: nn.Module) -> None:
        super().__init__()
        self.vgg, self.pixels = vgg, []

    def forward(self, img):
        self.pixels.append(img.shape[-2] * img.shape[-1])
        return self.vgg(img)


def _objective(vgg, crop: bool) -> StyleObjective:
    settings = resolve_settings("preview", "360", 4, crop_to_scene=crop, working_width=160, clip_available=False)
    style = np.random.default_rng(1).random((48, 64, 3)).astype(np.float32)
    return StyleObjective(style, settings, vgg=_SizeRecorder(vgg))


def test_cropped_losses_equal_the_whole_frames_and_cost_fewer_pixels(vgg):
    render, content, cov = _object_view()
    full, cropped = _objective(vgg, crop=False), _objective(vgg, crop=True)
    full.vgg.pixels.clear()
    cropped.vgg.pixels.clear()
    image_full = render.clone().requires_grad_(True)
    image_crop = render.clone().requires_grad_(True)
    total_full, terms_full = full(image_full, content, 0, coverage=cov)
    total_crop, terms_crop = cropped(image_crop, content, 0, coverage=cov)
    assert full._settings.weights.multiscale > 0  # the broad-strokes term on (no CLIP weights): on a wider box
    for term in ("nnfm", "content", "tv", "multiscale"):
        assert terms_crop[term] == pytest.approx(terms_full[term], rel=2e-3), term
    assert terms_crop["clip"] == pytest.approx(terms_full["clip"], rel=1e-5)  # the substitute sees the whole frame
    assert sum(cropped.vgg.pixels) < 0.6 * sum(full.vgg.pixels)
    total_full.backward()
    total_crop.backward()
    rows, cols = scene_box(cov)
    inside_full, inside_crop = image_full.grad[rows, cols], image_crop.grad[rows, cols]
    cos = torch.nn.functional.cosine_similarity(inside_full.flatten(), inside_crop.flatten(), dim=0)
    assert cos > 0.99
    outside = torch.ones_like(cov, dtype=torch.bool)
    outside[rows, cols] = False
    cropped.set_weights(StyleWeights(clip=0.0, nnfm=10.0, content=0.05, tv=0.0))  # the VGG terms alone
    image = render.clone().requires_grad_(True)
    cropped(image, content, 0, coverage=cov)[0].backward()
    assert torch.all(image.grad[outside] == 0) and image.grad[rows, cols].abs().sum() > 0  # VGG never looked there


def test_photos_and_switched_off_crops_see_whole_frames(vgg):
    render, content, cov = _object_view()
    off = _objective(vgg, crop=False)
    off.vgg.pixels.clear()
    off(render, content, 0, coverage=cov)
    on = _objective(vgg, crop=True)
    on.vgg.pixels.clear()
    on(render, content, 0, coverage=None)  # photos: no coverage is handed over
    assert max(off.vgg.pixels) == 96 * 160 and max(on.vgg.pixels) == 96 * 160  # (the substitute runs at 1/16)
