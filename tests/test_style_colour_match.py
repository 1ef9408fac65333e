"""Colour transfer: mean/covariance really match; degenerate inputs stay finite."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gstyle_core.style.colour_match import (
    apply_colour_transform,
    colour_statistics,
    colour_transfer_matrix,
    match_colours,
)


def _correlated(rng: np.random.Generator, n: int, mean, mix) -> np.ndarray:
    return rng.normal(size=(n, 3)) @ np.asarray(mix).T + np.asarray(mean)


def test_mean_and_covariance_match():
    rng = np.random.default_rng(0)
    content = _correlated(rng, 5000, [0.4, 0.5, 0.3], [[0.2, 0.05, 0], [0, 0.1, 0.02], [0.03, 0, 0.15]])
    style = _correlated(rng, 3000, [0.6, 0.2, 0.5], [[0.05, 0.1, 0.0], [0.02, 0.2, 0.0], [0, 0.04, 0.08]])
    transform, offset = colour_transfer_matrix(content, style)
    mapped = apply_colour_transform(content, transform, offset, clip=False).astype(np.float64)
    mean_m, cov_m = colour_statistics(mapped)
    mean_s, cov_s = colour_statistics(style)
    np.testing.assert_allclose(mean_m, mean_s, atol=1e-5)
    np.testing.assert_allclose(cov_m, cov_s, atol=1e-5)
    # A is the symmetric-root solution Σs^½ Σc^-½, so A Σc Aᵀ = Σs holds exactly too.
    _, cov_c = colour_statistics(content)
    np.testing.assert_allclose(transform @ cov_c @ transform.T, cov_s, atol=1e-10)


def test_identity_when_statistics_already_match():
    rng = np.random.default_rng(1)
    pixels = rng.uniform(size=(1000, 3))
    transform, offset = colour_transfer_matrix(pixels, pixels)
    np.testing.assert_allclose(transform, np.eye(3), atol=1e-8)
    np.testing.assert_allclose(offset, 0, atol=1e-8)


def test_clip_option_and_shapes():
    rng = np.random.default_rng(2)
    images = rng.uniform(size=(2, 8, 9, 3)).astype(np.float32)
    style = rng.uniform(0.8, 1.0, size=(50, 3)) * [1.0, 0.1, 0.1]
    clipped = match_colours(images, style)
    assert clipped.shape == images.shape and clipped.dtype == np.float32
    assert clipped.min() >= 0 and clipped.max() <= 1
    raw = match_colours(images, style, clip=False)
    assert raw.max() > 1 or raw.min() < 0  # the clip really did something here


@pytest.mark.parametrize("case", ["uniform_style", "grey_style", "one_colour_scene", "both_uniform",
                                  "huge_range", "two_colours", "single_pixel"])
def test_degenerate_inputs_stay_finite(case):
    rng = np.random.default_rng(3)
    content = rng.uniform(size=(500, 3))
    style = rng.uniform(size=(400, 3))
    if case == "uniform_style":
        style = np.tile([0.2, 0.7, 0.1], (400, 1))
    elif case == "grey_style":
        style = np.repeat(rng.uniform(size=(400, 1)), 3, axis=1)
    elif case == "one_colour_scene":
        content = np.tile([0.5, 0.5, 0.5], (500, 1)) + rng.normal(scale=1e-7, size=(500, 3))
    elif case == "both_uniform":
        content, style = np.full((10, 3), 0.3), np.full((10, 3), 0.9)
    elif case == "huge_range":
        content = content * 1e6
        style = style * 1e-6
    elif case == "two_colours":
        content = np.array([[0, 0, 0], [1, 1, 1]] * 50, dtype=float)
    elif case == "single_pixel":
        content = content[:1]
    transform, offset = colour_transfer_matrix(content, style)
    assert np.isfinite(transform).all() and np.isfinite(offset).all()
    out = apply_colour_transform(content, transform, offset, clip=False)
    assert np.isfinite(out).all()
    if case in ("uniform_style", "both_uniform"):
        np.testing.assert_allclose(out.mean(0), style[0], atol=1e-3)  # everything becomes the style colour


def test_non_finite_and_empty_inputs():
    content = np.array([[0.1, 0.2, 0.3], [np.nan, 0, 0], [0.5, 0.5, np.inf], [0.3, 0.1, 0.2]])
    transform, offset = colour_transfer_matrix(content, np.eye(3))
    assert np.isfinite(transform).all() and np.isfinite(offset).all()
    with pytest.raises(ValueError, match="empty"):
        colour_transfer_matrix(np.zeros((0, 3)), np.eye(3))
    with pytest.raises(ValueError, match=r"\[\.\.\., 3\]"):
        colour_transfer_matrix(np.zeros((4, 2)), np.eye(3))


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 30), st.just(3)), elements=st.floats(0, 1)),
       arrays(np.float64, st.tuples(st.integers(1, 30), st.just(3)), elements=st.floats(0, 1)))
def test_any_colours_in_unit_range_give_finite_clipped_output(content, style):
    transform, offset = colour_transfer_matrix(content, style)
    out = apply_colour_transform(content, transform, offset)
    assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
