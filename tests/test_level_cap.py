"""A run on photos ends at most at the photos' width: a level wider than them would fit enlarged photos."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import blob_scene, ring_cameras
from test_resume_phases import NoisyPull

from gstyle_core.engine.levels import capped_levels
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer


@pytest.mark.parametrize(("widths", "limit", "expected"), [
    ((512, 1024), 504, (504,)),  # the fern's photos: both levels become one at their width
    ((512, 1024), 800, (512, 800)),
    ((512, 1024), 2000, (512, 1024)),
    ((512,), 256, ()),  # no finer than the working width: no level
    ((512, 1024), None, (512, 1024)),  # rendered ground truth: any width
])
def test_levels_are_capped_at_the_limit(widths, limit, expected):
    assert capped_levels(widths, 256, limit) == expected


def style() -> np.ndarray:
    img = np.zeros((8, 8, 3), np.float32)
    img[..., 0], img[::2, :, 2] = 1.0, 0.6
    return img


def engine(photos: bool, widths=(64, 128)) -> Stylizer:
    cams = ring_cameras(3, width=80, height=60)
    settings = resolve_settings("preview", "forward", 3, max_views=3, epochs=1, min_steps=0, working_width=32,
                                preprocess_rounds=0, split_rate=0.0, refine_widths=widths, refine_epochs=1)
    shots = [np.full((60, 80, 3), 0.4, np.float32)] * 3 if photos else None
    return Stylizer(blob_scene(120, seed=1), cams, style(), settings, objective_factory=NoisyPull, photos=shots)


def test_a_run_on_photos_ends_at_their_width_and_says_so():
    eng = engine(photos=True)
    assert eng.levels == (32, 64, 80)
    assert "the photos are 80 px wide, so the run ends at 80 px" in eng.decisions["levels_capped"]
    assert eng.next_level_width() is None
    with pytest.raises(ValueError, match="the photos' width"):
        eng.refine()
    eng.run()
    assert eng.phases[-2].name == "refine_1" and eng.phases[-2].cameras[0].width == 80


def test_refine_stops_at_the_photos_width():
    eng = engine(photos=True, widths=())
    assert eng.next_level_width() == 64
    eng.refine()
    assert eng.next_level_width() == 80  # twice 64 is wider than the photos: their width
    with pytest.raises(ValueError, match="enlarged"):
        eng.refine(128)
    assert eng.refine() == 80 and eng.next_level_width() is None


def test_rendered_ground_truth_keeps_every_level():
    eng = engine(photos=False)
    assert eng.levels == (32, 64, 128) and "levels_capped" not in eng.decisions
    assert eng.next_level_width() == 256
