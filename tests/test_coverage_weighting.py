"""Losses over the scene only: coverage-weighted NNFM, content and coarse substitute; the engine's coverage hand-off."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.style.clip import CoarseStyleLoss
from gstyle_core.style.features import feature_weights, weighted_mean
from gstyle_core.style.losses import StyleLoss, content_loss
from gstyle_core.style.nnfm import StyleTarget, nnfm_loss
from tests.fakes import MeanColourPull
from tests.synthetic import blob_scene, ring_cameras


def _left_half_mask(h: int, w: int) -> torch.Tensor:
    mask = torch.zeros(h, w)
    mask[:, : w // 2] = 1.0
    return mask


def test_feature_weights_pool_coverage_to_the_grid():
    mask = _left_half_mask(16, 16)
    w = feature_weights(mask, (4, 4))
    assert w.shape == (1, 1, 4, 4)
    torch.testing.assert_close(w[0, 0, :, :2], torch.ones(4, 2))
    torch.testing.assert_close(w[0, 0, :, 2:], torch.zeros(4, 2))
    assert feature_weights(None, (4, 4)) is None
    assert weighted_mean(torch.ones(1, 3, 2, 2), torch.zeros(1, 1, 2, 2)).item() == 0.0  # nothing in view


def test_uncovered_positions_neither_count_nor_get_gradient():
    torch.manual_seed(1)
    render = torch.randn(1, 16, 6, 8, requires_grad=True)
    gt = torch.randn(1, 16, 6, 8)
    style = torch.randn(16, 5, 5)
    grid = feature_weights(_left_half_mask(6, 8), (6, 8))

    nnfm = nnfm_loss(render, style, weights=grid)
    content = content_loss(render, gt, weights=grid)
    (nnfm + content).backward()
    assert torch.all(render.grad[..., 4:] == 0) and render.grad[..., :4].abs().sum() > 0
    # equal to the plain losses on the covered half alone
    left = render.detach()[..., :4]
    torch.testing.assert_close(nnfm.detach(), nnfm_loss(left, style), atol=1e-6, rtol=1e-6)
    torch.testing.assert_close(content.detach(), content_loss(left, gt[..., :4]), atol=1e-6, rtol=1e-6)
    # full coverage is the plain mean
    ones = torch.ones(1, 1, 6, 8)
    torch.testing.assert_close(nnfm_loss(render, style, weights=ones), nnfm_loss(render, style))
    torch.testing.assert_close(content_loss(render, gt, weights=ones), content_loss(render, gt))


def test_substitute_statistics_ignore_the_background(vgg):
    style = torch.rand(1, 3, 64, 64)
    coarse = CoarseStyleLoss(vgg, style, downsample=1)
    mask = _left_half_mask(64, 128)
    render = torch.rand(1, 3, 64, 128)
    black, white = render.clone(), render.clone()
    black[..., 64:] = 0.0
    white[..., 64:] = 1.0
    # pooled coverage is 1 only well inside the object; compare two renders that differ only far in the background
    far = torch.zeros(64, 128)
    far[:, :40] = 1.0
    assert coarse(black, far).item() == pytest.approx(coarse(white, far).item(), rel=1e-5)
    assert coarse(black).item() != pytest.approx(coarse(white).item(), rel=1e-3)  # whole frame: it counts
    torch.testing.assert_close(coarse(render, torch.ones(64, 128)), coarse(render), atol=1e-5, rtol=1e-5)
    assert torch.isfinite(coarse(render, torch.zeros(64, 128)))  # empty coverage falls back to the whole frame
    assert coarse(render, mask).item() > 0


def test_style_loss_with_full_coverage_equals_without(vgg):
    torch.manual_seed(2)
    style = torch.rand(1, 3, 48, 48)
    loss_fn = StyleLoss(vgg, StyleTarget.from_image(vgg, style), CoarseStyleLoss(vgg, style))
    render, gt = torch.rand(1, 3, 40, 56), torch.rand(1, 3, 40, 56)
    total, terms = loss_fn(render, gt)
    total_cov, terms_cov = loss_fn(render, gt, coverage=torch.ones(40, 56))
    assert total_cov.item() == pytest.approx(total.item(), rel=1e-5)
    assert terms_cov == pytest.approx(terms, rel=1e-5)
    _, half = loss_fn(render, gt, coverage=_left_half_mask(40, 56))
    assert half["nnfm"] != pytest.approx(terms["nnfm"], rel=1e-4)


class _CoverageRecorder(MeanColourPull):
    seen: list = []

    def __call__(self, image, content, view, coverage=None):
        _CoverageRecorder.seen.append(None if coverage is None else coverage.clone())
        return super().__call__(image, content, view, coverage)


@pytest.mark.parametrize("with_photos", [False, True])
def test_engine_hands_the_scene_coverage_only_for_rendered_ground_truth(with_photos):
    cams = ring_cameras(2)
    settings = resolve_settings("preview", "forward", 2, max_views=2, epochs=1, min_steps=2, refit_iterations=0,
                                preprocess_rounds=0, working_width=32, split_rate=0.0)
    photos = [np.full((c.height, c.width, 3), 0.5, np.float32) for c in cams] if with_photos else None
    style = np.random.default_rng(0).random((8, 8, 3)).astype(np.float32)
    _CoverageRecorder.seen = []
    eng = Stylizer(blob_scene(60, seed=2), cams, style, settings, objective_factory=_CoverageRecorder, photos=photos)
    while not eng.done:
        eng.step()
    assert len(_CoverageRecorder.seen) == 2
    if with_photos:
        assert all(c is None for c in _CoverageRecorder.seen)
    else:
        for view, cov in enumerate(_CoverageRecorder.seen):
            torch.testing.assert_close(cov, eng.coverage[view])
            assert 0.0 < float(cov.mean()) < 1.0  # the blobs do not fill the frame
