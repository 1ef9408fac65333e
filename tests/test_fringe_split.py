"""The 360° pre-processing split of every CPU tier (preview, balanced, final) keeps the scene's coverage (issue #50
item 4, the fringe halo): children of a flat Gaussian that cover only a fifth of their parent's footprint left the
soft fringe they made as specks, which a short refit could not close and stylization turned into a halo of bright
strokes (docs/notes/display-size.md, "The fringe halo"; docs/notes/tradeoffs.md for balanced and final)."""

from __future__ import annotations

import numpy as np
import pytest
from fakes import MeanColourPull
from synthetic import blob_scene, ring_cameras

from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.fit.model import scene_from_params
from gstyle_core.scene_images import render_scene_image


def _coverage(scene, cameras) -> float:
    return float(sum(render_scene_image(scene, c, with_alpha=True)[1].sum() for c in cameras))


@pytest.mark.parametrize("preset", ["preview", "balanced", "final"])
def test_the_360_split_keeps_the_scene_coverage(preset):
    scene = blob_scene(200, seed=5, scale=0.04)
    scene.log_scales[:12, :2] += np.log(5.0)  # a few large flat Gaussians: the ones the split picks
    settings = resolve_settings(preset, "360", 3, clip_available=False, max_views=3, working_width=48,
                                refit_iterations=0, force_preprocess=True, preprocess_rounds=1)  # one split alone
    engine = Stylizer(scene, ring_cameras(3), np.full((8, 8, 3), 0.5, np.float32), settings,
                      objective_factory=MeanColourPull)
    while engine.phase in ("ground_truth", "preprocess"):
        engine.step()
    assert engine.gaussian_count > scene.count  # the flat ones were split
    cameras = [c.resized_to_width(192) for c in ring_cameras(3)]
    kept = _coverage(scene_from_params(engine.params), cameras) / _coverage(scene, cameras)
    assert 0.95 < kept < 1.05  # children at 1/6.4 of their parent's scale kept 0.71 of it
