"""The texture-scale figure: difference-of-Gaussian band energies of the added texture and of the painting."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from gstyle_core.style.texture_scale import (
    BAND_NAMES,
    added_texture_shares,
    band_energies,
    band_shares,
    gaussian_blur,
    matched_side,
    painting_shares,
    texture_scale,
)


def _stripes(period: float, h: int = 96, w: int = 128) -> np.ndarray:
    """Vertical sinusoidal stripes of ``period`` px as an [H, W, 3] image in [0, 1]."""
    x = np.arange(w)
    row = 0.5 + 0.4 * np.sin(2 * np.pi * x / period)
    return np.repeat(np.tile(row, (h, 1))[..., None], 3, axis=-1)


def test_blur_is_scipy_gaussian_filter():
    ndimage = pytest.importorskip("scipy.ndimage")
    x = np.random.default_rng(0).random((17, 23))  # smaller than the σ 10 kernel: reflections repeat
    for sigma in (0.5, 1.5, 4.0, 10.0):
        ours = gaussian_blur(torch.as_tensor(x)[None], sigma)[0].numpy()
        np.testing.assert_allclose(ours, ndimage.gaussian_filter(x, sigma), atol=1e-12)


def test_shares_follow_the_pattern_size():
    fine, middle, coarse = (band_shares(_stripes(p)) for p in (3.0, 12.0, 40.0))
    assert np.argmax(fine) == 0 and np.argmax(middle) == 1 and np.argmax(coarse) == 2
    for s in (fine, middle, coarse):
        assert s.sum() == pytest.approx(1.0)
    assert band_shares(np.full((20, 20, 3), 0.3)).tolist() == [0.0, 0.0, 0.0]  # no detail, no shares


def test_channels_are_measured_separately():
    img = _stripes(6.0)
    one = band_energies(img[..., :1])
    np.testing.assert_allclose(band_energies(img), 3 * one)
    opposed = img.copy()
    opposed[..., 1] = 1.0 - opposed[..., 0]  # its grey level would cancel the stripes; per channel it does not
    assert band_energies(opposed).sum() == pytest.approx(band_energies(img).sum())


def test_the_mask_selects_where_energy_counts():
    img = np.concatenate([_stripes(3.0, w=96), _stripes(40.0, w=96)], axis=1)
    left = np.zeros(img.shape[:2])
    left[:, 10:80] = 1.0
    right = np.zeros(img.shape[:2])
    right[:, 110:180] = 1.0
    assert np.argmax(band_shares(img, left)) == 0
    assert np.argmax(band_shares(img, right)) == 2


def test_added_texture_ignores_what_was_there():
    rng = np.random.default_rng(1)
    before = rng.random((64, 96, 3)) * 0.5  # fine noise in the scene before
    added = _stripes(40.0, 64, 96) * 0.5
    np.testing.assert_allclose(added_texture_shares(before, before + added), band_shares(added))
    with pytest.raises(ValueError):
        added_texture_shares(before, before[:, :10])


def test_a_larger_painting_has_a_coarser_share():
    painting = np.random.default_rng(2).random((40, 60, 3)).astype(np.float32)
    small, large = painting_shares(painting, 60), painting_shares(painting, 240)
    assert large[2] > 2 * small[2]
    assert small[0] > large[0]


def test_matched_side_in_the_measured_images_pixels():
    assert matched_side(256, 1.0) == 256
    assert matched_side(256, 2.0, 256) == 512
    assert matched_side(384, 1.0, 256) == 256  # the painting at 384 px against 384-px renders = 256 against 256
    assert matched_side(256, 0.5, 512) == 256


def test_figure_over_views_and_paintings():
    before = [np.zeros((48, 64, 3)), np.zeros((48, 64, 3))]
    after = [_stripes(3.0, 48, 64), _stripes(40.0, 48, 64)]
    fig = texture_scale(before, after, None, _stripes(12.0), 64)
    energy = band_energies(after[0]) + band_energies(after[1])
    np.testing.assert_allclose(fig.added, energy / energy.sum())
    np.testing.assert_allclose(fig.painting, painting_shares(_stripes(12.0), 64))
    assert fig.coarse_ratio == pytest.approx(fig.added[2] / fig.painting[2])
    d = fig.to_dict()
    assert list(d["added"]) == list(BAND_NAMES) and d["painting_side"] == 64
    assert f"{fig.added[0]:.2f}" in fig.line()
    mixed = texture_scale(before[0], after[0], None, [_stripes(3.0), _stripes(40.0)], 64, [1.0, 0.0])
    np.testing.assert_allclose(mixed.painting, painting_shares(_stripes(3.0), 64))
    with pytest.raises(ValueError):
        texture_scale(before, after[:1], None, _stripes(12.0), 64)


def test_the_run_figure_takes_the_paintings_luminance_with_keep_colours():
    """With keep colours only the painting's light-and-dark pattern is transferred, so the figure compares the added
    texture with the painting's luminance; without, with the painting as it is."""
    from types import SimpleNamespace

    from gstyle_core.engine.run_figures import run_texture_scale
    from gstyle_core.style.keep_colours import grey
    from gstyle_core.style.texture_scale import matched_side, texture_scale

    rng = np.random.default_rng(4)
    painting = rng.random((40, 60, 3)).astype(np.float32)
    painting[..., 0] = np.linspace(0, 1, 60)[None, :]  # a colour ramp: its own bands differ from the luminance's
    before = [rng.random((32, 48, 3)).astype(np.float32)]
    after = [np.clip(before[0] + 0.1 * rng.standard_normal((32, 48, 3)), 0, 1).astype(np.float32)]
    alpha = [np.ones((32, 48), np.float32)]
    side = matched_side(64, 1.0, 48)
    for keep in (False, True):
        engine = SimpleNamespace(settings=SimpleNamespace(working_width=64, style_scale=1.0, style_weights=(),
                                                          keep_colours=keep))
        figure = run_texture_scale(engine, painting, before, after, alpha, 48)
        expected = texture_scale(before, after, alpha, [grey(painting) if keep else painting], side, None)
        assert figure.painting == pytest.approx(expected.painting) and figure.added == pytest.approx(expected.added)
    assert run_texture_scale(engine, painting, before, after, alpha, 48).painting != pytest.approx(
        texture_scale(before, after, alpha, [painting], side, None).painting, abs=1e-3)
