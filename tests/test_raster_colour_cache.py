"""Colour-only fast path: cached blend weights reproduce the full render and its colour gradient."""

from __future__ import annotations

import pytest
import torch

from gstyle_core.raster import ColourCache, ColourCacheStore, rasterize
from gstyle_core.raster.synthetic import random_scene


def _cache(scene, version=0):
    return ColourCache(
        scene.means,
        scene.quats,
        scene.scales,
        scene.opacities,
        scene.viewmat,
        scene.K,
        scene.width,
        scene.height,
        geometry_version=version,
    )


def test_cache_render_matches_full_render_and_colour_gradient():
    scene = random_scene(400, width=45, height=38, seed=21, scale_range=(0.05, 0.3))
    background = torch.tensor([0.3, 0.1, 0.7])
    weight = torch.randn(38, 45, 3, generator=torch.Generator().manual_seed(2))
    colors_full = scene.colors.clone().requires_grad_(True)
    full = rasterize(
        scene.means,
        scene.quats,
        scene.scales,
        scene.opacities,
        colors_full,
        scene.viewmat,
        scene.K,
        45,
        38,
        background=background,
    )
    (full.image * weight).sum().backward()

    cache = _cache(scene)
    colors_cached = scene.colors.clone().requires_grad_(True)
    image = cache.render(colors_cached, background)
    (image * weight).sum().backward()
    assert float((image.detach() - full.image.detach()).abs().max()) <= 1e-5
    assert float(full.alpha.detach().mean()) > 0.5
    rel = (colors_cached.grad - colors_full.grad).norm() / colors_full.grad.norm()
    assert float(rel) <= 1e-5
    # Other colours, same weights: still the full render.
    new_colors = torch.rand(400, 3, generator=torch.Generator().manual_seed(3))
    again = rasterize(
        scene.means,
        scene.quats,
        scene.scales,
        scene.opacities,
        new_colors,
        scene.viewmat,
        scene.K,
        45,
        38,
        background=background,
    )
    assert float((cache.render(new_colors, background) - again.image).abs().max()) <= 1e-5


def test_cache_rejects_wrong_colour_shape():
    cache = _cache(random_scene(10, width=8, height=8))
    with pytest.raises(ValueError, match="colors"):
        cache.render(torch.zeros(9, 3))


def test_store_reuses_and_invalidates_on_geometry_change():
    scene = random_scene(120, width=24, height=24, seed=5)
    store = ColourCacheStore()
    builds = []

    def build(version):
        def make():
            builds.append(version)
            return _cache(scene, version)

        return make

    first = store.get_or_build(0, 1, build(1))
    assert store.get_or_build(0, 1, build(1)) is first and builds == [1]
    store.get_or_build(3, 1, build(1))
    assert len(store) == 2

    # Move the geometry: a new version drops every cache and the rebuilt one renders the new geometry.
    scene.means = scene.means + torch.tensor([0.3, 0.0, 0.0])
    assert store.get(0, 2) is None and len(store) == 0
    moved = store.get_or_build(0, 2, build(2))
    assert moved is not first and builds == [1, 1, 2]
    full = rasterize(*scene.params(), scene.viewmat, scene.K, 24, 24)
    assert float((moved.render(scene.colors) - full.image).abs().max()) <= 1e-5
    assert float((first.render(scene.colors) - full.image).abs().max()) > 1e-2  # the stale cache differs

    store.invalidate()
    assert len(store) == 0 and store.get(0, 2) is None
