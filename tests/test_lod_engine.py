"""The engine on a level-of-detail cut (``engine/lod_run.py``): the cut said before the first step, every input
Gaussian written and shown, the region's outside exact, resume keeps the lineage, ``--lod off`` as before."""

from __future__ import annotations

import numpy as np
import pytest
from fakes import MeanColourPull

from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.scene_images import load_scene_and_cameras


@pytest.fixture(scope="module")
def demo():
    scene, _report, cams = load_scene_and_cameras(None, None)
    return scene, cams.cameras


def _style() -> np.ndarray:
    style = np.zeros((8, 8, 3), np.float32)
    style[..., 2] = 1.0
    style[::2, :, 0] = 0.6
    return style


def _engine(demo, selection=None, **overrides) -> Stylizer:
    scene, cameras = demo
    opts = dict(max_views=4, epochs=1.0, min_steps=4, refit_iterations=2, split_at=(0.5,), working_width=64)
    opts.update(overrides)
    settings = resolve_settings("preview", "360", len(cameras), **opts)
    return Stylizer(scene, cameras, _style(), settings, objective_factory=MeanColourPull, selection=selection)


def test_a_run_on_a_cut_holds_parents_and_writes_and_shows_every_input_gaussian(demo):
    scene, _ = demo
    engine = _engine(demo)
    assert engine.lod is not None
    said = f"{scene.count:,} Gaussians as {engine.lod.parent_count:,} parents at 64 px"
    assert engine.decisions["lod"].startswith(said)
    assert engine.gaussian_count == engine.lod.parent_count < scene.count
    engine.run()
    result = engine.stylized_scene()
    assert result.count >= scene.count
    merged = np.flatnonzero(engine.lod.merged[engine.lod.child_parent])
    assert np.array_equal(result.means[-len(merged):], scene.means[merged])  # each child with its own geometry
    snap = engine.snapshot()
    assert len(snap["means"]) == result.count  # the viewer shows what the export writes
    assert np.array_equal(snap["means"], result.means)
    assert np.allclose(snap["colors"], np.clip(result.rgb, 0, 1), atol=1e-5)
    assert not np.allclose(result.rgb[-len(merged):], scene.rgb[merged], atol=1e-3)  # the children were stylized


def test_lod_off_holds_every_gaussian(demo):
    scene, _ = demo
    engine = _engine(demo, lod="off")
    assert engine.lod is None and engine.gaussian_count == scene.count
    assert engine.decisions["lod"].startswith("off")


def test_a_region_on_a_cut_leaves_its_outside_exactly_as_it_came(demo):
    scene, _ = demo
    selection = scene.means[:, 0] > np.median(scene.means[:, 0])
    engine = _engine(demo, selection=selection)
    assert engine.lod is not None and engine.lod.merged.any()
    engine.run()
    result = engine.stylized_scene()
    rows = {tuple(m): i for i, m in enumerate(result.means)}
    outside = np.flatnonzero(~selection)
    found = [rows.get(tuple(scene.means[k])) for k in outside]
    assert None not in found
    assert np.array_equal(result.sh_dc[found], scene.sh_dc[outside])


def test_a_resumed_run_on_a_cut_ends_as_the_uninterrupted_one(demo):
    whole = _engine(demo)
    whole.run()
    first = _engine(demo)
    for _ in range(30):
        first.step()
    state = first.state_dict()
    assert state["run"]["lineage"] is not None
    second = _engine(demo)
    second.load_state_dict(state)
    second.run()
    assert np.allclose(second.stylized_scene().sh_dc, whole.stylized_scene().sh_dc, atol=1e-5)
    off = _engine(demo, lod="off")
    with pytest.raises(ValueError, match="level of detail"):
        off.load_state_dict(state)
