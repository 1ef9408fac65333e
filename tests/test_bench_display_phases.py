"""bench/studies/display_phases.py's phase-by-phase probe on a tiny engine: its NNFM drop at the working width is the
figure the run itself reports (``evaluate_run``), at every phase boundary, with 0 for the input."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from fakes import MeanColourPull
from synthetic import blob_scene, ring_cameras

from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench" / "studies"))

import display_phases  # noqa: E402


def _style() -> np.ndarray:
    img = np.zeros((8, 8, 3), np.float32)
    img[..., 0], img[::2, :, 2] = 1.0, 0.7
    return img


def _engine() -> Stylizer:
    """A tiny real engine (3 ring views, 32 px, a 64-px level) pulled towards a red painting."""
    settings = resolve_settings("balanced", "forward", 3, max_views=3, epochs=2, min_steps=0, preprocess_rounds=0,
                                split_rate=0.0, working_width=32, refine_widths=(64,))
    return Stylizer(blob_scene(60, seed=4), ring_cameras(3), _style(), settings, objective_factory=MeanColourPull)


@pytest.fixture()
def one_network(monkeypatch):
    """Every VGG the figures load is one randomly initialised network (no weights on disk needed)."""
    from gstyle_core.style import vgg as vgg_module

    torch.manual_seed(0)
    net = vgg_module.VGGFeatures().eval()
    monkeypatch.setattr(vgg_module, "load_vgg", lambda *a, **k: net)
    monkeypatch.setattr(display_phases, "load_vgg", lambda *a, **k: net)


def test_each_stage_carries_the_drop_the_run_reports_at_its_working_width(one_network):
    from gstyle_core.engine.run_figures import evaluate_run

    engine = _engine()
    scene_in, style = engine.input_scene, _style()
    assert display_phases.working_width_drop(engine, scene_in, style)(scene_in) == 0.0
    rows = display_phases.stage_speckles(engine, scene_in, style, 64)
    stages = [r["stage"] for r in rows]
    assert stages[-1] == "result" and "after stylize" in stages and "after refine_0" in stages
    assert all(np.isfinite(r["nnfm_drop_working"]) for r in rows)
    reported = evaluate_run(engine, scene_in, style, width=engine.settings.working_width)["nnfm_drop"]
    assert rows[-1]["nnfm_drop_working"] == pytest.approx(reported, abs=1e-6)
    assert rows[-1]["nnfm_drop_working"] != rows[stages.index("after colour_match")]["nnfm_drop_working"]


def test_level_weights_reach_the_levels_steps_alone():
    engine = _engine()
    display_phases.with_level_weights(engine, display_phases.parse_weights("nnfm=400, edges=4000"))
    run = engine.run_state
    level = run.level_objective(64, None)
    assert (level.weights.nnfm, level.weights.edges) == (400.0, 4000.0)
    assert run.level_objective(64, None) is level  # built once, as the engine's own
    assert (run.objective_fn().weights.nnfm, run.objective_fn().weights.edges) == (engine.settings.weights.nnfm, 0.0)
    with pytest.raises(ValueError, match="unknown λ weight 'strokes'"):
        display_phases.parse_weights("strokes=2")
