"""Pre-processing refits of a run with finer levels hold the width the run ends at (docs/notes/tradeoffs.md, "Where the
structure at 1024 px goes"): every other iteration fits a window of the ground truth at that width, as large as a
working-width view, drawn from the seed and the iteration. What it does to the structure at a display's size is
measured on real captures by ``bench/studies/display_phases.py`` (on a small synthetic blob it helps or hurts by a few
per cent with the blob's sizes, too little to test); a resumed refit draws the same windows
(``test_resume_phases.py``)."""

from __future__ import annotations

import numpy as np
import torch
from fakes import MeanColourPull
from synthetic import blob_scene, ring_cameras

from gstyle_core.engine.levels import end_width
from gstyle_core.engine.phases.end_width_crops import EndWidthCrops
from gstyle_core.engine.phases.refit import Refit
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.fit.model import params_from_scene, render_params

WORKING, END = 32, 128


def _engine(refine_widths, refit_iterations=6, scene=None):
    scene = scene or blob_scene(120, seed=3, scale=0.03)
    settings = resolve_settings("balanced", "360", 4, clip_available=False, max_views=4, working_width=WORKING,
                                refine_widths=refine_widths, refit_iterations=refit_iterations,
                                force_preprocess=True, preprocess_rounds=1)
    return Stylizer(scene, ring_cameras(4, width=96, height=80), np.full((8, 8, 3), 0.5, np.float32), settings,
                    objective_factory=MeanColourPull)


def test_a_window_is_the_part_of_the_end_width_view_its_camera_sees():
    engine = _engine((END,))
    run = engine.run_state
    crops = EndWidthCrops(run, END)
    cam, gt = crops.window(seed=7, iteration=3, size=(WORKING, 27))
    assert (cam.width, cam.height) == (WORKING, 27) == (gt.shape[1], gt.shape[0])
    with torch.no_grad():
        seen = render_params(params_from_scene(run.input_scene, requires_grad=False), cam, sh_degree=0).image
    diff = (seen - gt).abs()  # the crop camera renders that window (tiles cut at other pixels: a few 1e-4 off)
    assert float(diff.max()) < 2e-3 and float(diff.mean()) < 2e-5
    again_cam, again = crops.window(seed=7, iteration=3, size=(WORKING, 27))
    assert torch.equal(again, gt) and (again_cam.cx, again_cam.cy) == (cam.cx, cam.cy)  # drawn from seed, iteration
    other = [crops.window(seed=7, iteration=k, size=(WORKING, 27))[0] for k in range(4, 12)]
    assert len({(c.cx, c.cy) for c in other}) > 1
    assert len(run.end_targets["images"]) <= len(crops.views)  # one ground truth per view drawn, kept for the run
    assert EndWidthCrops(run, END).images is run.end_targets["images"]


def test_only_runs_with_finer_levels_refit_on_end_width_windows():
    with_levels, without = _engine((END,)), _engine(())
    assert end_width(with_levels.settings) == END and end_width(without.settings) == WORKING
    assert Refit.preprocessing(with_levels.run_state).crops is not None
    assert Refit.preprocessing(without.run_state).crops is None
    for engine in (with_levels, without):
        while engine.phase in ("ground_truth", "preprocess"):
            engine.step()
    assert with_levels.run_state.end_targets["images"]  # its refit fitted windows at the end width
    assert getattr(without.run_state, "end_targets", None) is None
