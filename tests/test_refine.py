"""Finer levels (coarse to fine, issue #34): the run goes on from its colours at finer widths, on crops or whole
views; a level resumed from a checkpoint ends exactly as an uninterrupted one."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from synthetic import blob_scene, ring_cameras
from test_resume_phases import NoisyPull

from gstyle_core.engine.checkpoint import read_checkpoint, save_checkpoint
from gstyle_core.engine.levels import check_refine_widths, level_widths, next_width
from gstyle_core.engine.phases.refine import covered_box, random_window
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.scene_images import render_scene_image


def style() -> np.ndarray:
    img = np.zeros((8, 8, 3), np.float32)
    img[..., 0] = 1.0
    img[::2, :, 2] = 0.6
    return img


def make_engine(mode: str = "crops", widths=(64,), **kw) -> Stylizer:
    settings = resolve_settings("preview", "360", 4, max_views=4, epochs=2, min_steps=0, working_width=32,
                                refit_iterations=2, preprocess_rounds=0, split_rate=0.0, max_gaussians=10_000,
                                refine_widths=widths, refine_mode=mode, refine_epochs=4, **kw)
    return Stylizer(blob_scene(200, seed=3), ring_cameras(4), style(), settings, objective_factory=NoisyPull)


class RecordingPull(NoisyPull):
    """NoisyPull that records the size of every image it is given."""

    sizes: list[tuple[int, int]] = []

    def __call__(self, image, content, view, coverage=None):
        RecordingPull.sizes.append(tuple(image.shape[:2]))
        assert content.shape == image.shape and (coverage is None or coverage.shape == image.shape[:2])
        return super().__call__(image, content, view, coverage)


def test_levels_come_after_the_stylization_and_count_in_the_progress():
    engine = make_engine(widths=(48, 64))
    names = [p.name for p in engine.phases]
    assert names == ["ground_truth", "preprocess", "colour_match", "stylize", "refine_0", "refine_1", "finish"]
    planned = engine.total_steps()
    phases, totals = [], set()
    while not engine.done:
        rep = engine.step()
        phases.append(rep.phase)
        totals.add(rep.total_steps)
    assert totals == {planned} == {engine.global_step}
    assert phases.index("refine") > max(i for i, p in enumerate(phases) if p == "stylize")
    assert phases[-1] == "finish" and "refine" in engine.timings
    level = engine.phases[5]
    assert [c.width for c in level.cameras] == [64] * 4 and len(level.gt) == 4


@pytest.mark.parametrize("mode", ["crops", "whole"])
def test_a_level_renders_crops_or_whole_views_at_its_width(mode):
    RecordingPull.sizes = []
    settings = resolve_settings("preview", "360", 4, max_views=4, epochs=1, min_steps=0, working_width=32,
                                preprocess_rounds=0, split_rate=0.0, refine_widths=(96,), refine_mode=mode,
                                refine_epochs=2)
    engine = Stylizer(blob_scene(200, seed=3), ring_cameras(4), style(), settings, objective_factory=RecordingPull)
    while engine.phase != "refine":
        engine.step()
    RecordingPull.sizes = []
    while engine.phase == "refine":
        engine.step()
    small, full = (27, 32), (80, 96)  # the working-width view (32 × 27) and the level's (96 × 80)
    # steps at the level's width (crops: its pixels, a working view's size; whole: the whole view) alternate with
    # whole views at 32
    assert set(RecordingPull.sizes) == ({small} if mode == "crops" else {small, full})
    level = engine.phases[4]
    assert level.crop_step(0) and not level.crop_step(1)
    if mode == "whole":
        assert RecordingPull.sizes[0] == full and RecordingPull.sizes.count(full) * 2 >= len(RecordingPull.sizes)


def test_a_crop_renders_what_the_whole_view_shows_there():
    scene = blob_scene(300, seed=4)
    cam = ring_cameras(1, width=96, height=80)[0]
    whole = render_scene_image(scene, cam)
    part = render_scene_image(scene, cam.cropped(20, 12, 40, 30))
    assert part.shape == (30, 40, 3)
    np.testing.assert_allclose(part, whole[12:42, 20:60], atol=5e-3)
    with pytest.raises(ValueError, match="at least 1"):
        cam.cropped(0, 0, 0, 10)


def test_windows_lie_in_the_frame_over_the_covered_box():
    gen = torch.Generator().manual_seed(0)
    for _ in range(50):
        x0, y0 = random_window((30, 20, 90, 50), (100, 80), (40, 20), gen)
        assert 30 <= x0 <= 50 and 20 <= y0 <= 30  # inside the box where it is larger than the window
    assert random_window((40, 10, 50, 20), (100, 80), (40, 30), gen) == (25, 0)  # centred, kept in the frame
    assert random_window((0, 0, 10, 10), (20, 20), (40, 40), gen) == (0, 0)
    alpha = torch.zeros(10, 12)
    alpha[2:5, 3:9] = 1.0
    assert covered_box(alpha) == (3, 2, 9, 5)
    assert covered_box(torch.zeros(4, 6)) == (0, 0, 6, 4)


def test_level_widths_are_checked():
    assert check_refine_widths([512, 1024], 256) == (512, 1024)
    assert level_widths(256, (512,)) == (256, 512) and next_width((256, 512)) == 1024
    for bad, why in (((512, 512), "coarse to fine"), ((128,), "coarse to fine"), ((8,), "16 to 4096"),
                     ((10_000,), "16 to 4096")):
        with pytest.raises(ValueError, match=why):
            check_refine_widths(bad, 256)
    with pytest.raises(ValueError, match="coarse to fine"):
        resolve_settings("preview", "360", 4, working_width=256, refine_widths=(128,))
    with pytest.raises(ValueError, match="refine_mode"):
        resolve_settings("preview", "360", 4, refine_mode="tiles")


@pytest.mark.parametrize("mode", ["crops", "whole"])
def test_a_run_resumed_inside_a_level_ends_as_an_uninterrupted_one(mode, tmp_path):
    reference = make_engine(mode)
    saved, reports = {}, []
    while not reference.done:
        level = reference.phases[4]
        where = None
        if reference.phase == "refine" and len(level.gt) == 2:
            where = "inside the level's ground truth"
        elif reference.phase == "refine" and level.step_index == 3:
            where = "inside the level's steps"
        if where is not None and where not in saved:
            path = save_checkpoint(tmp_path / f"{len(saved)}.ckpt", reference.state_dict(), {"kind": "test"})
            saved[where] = (reference.global_step, read_checkpoint(path)[0])
        rep = reference.step()
        reports.append((rep.phase, rep.step, rep.total_steps, rep.message, rep.losses))
    assert len(saved) == 2
    for where, (step, state) in saved.items():
        resumed = make_engine(mode)
        resumed.load_state_dict(state)
        tail = []
        while not resumed.done:
            rep = resumed.step()
            tail.append((rep.phase, rep.step, rep.total_steps, rep.message, rep.losses))
        assert tail == reports[step:], where  # the targets were taken again as the checkpoint loaded
        assert torch.equal(resumed.c_s, reference.c_s), where


def test_a_checkpoint_of_another_level_is_refused():
    state = make_engine("crops").state_dict()
    with pytest.raises(ValueError, match="crops level at 64 px"):
        make_engine("whole").load_state_dict(state)


def test_refine_carries_a_finished_run_on_at_the_next_width_and_a_resumed_run_keeps_it(tmp_path):
    engine = make_engine(widths=())
    engine.run()
    assert engine.levels == (32,) and engine.current_width == 32 and engine.done
    before = engine.c_s.clone()
    w = engine.settings.weights
    assert (w.nnfm, w.edges, w.multiscale, w.chroma_tv) == (200.0, 0.0, 200.0, 3000.0)  # a calibrated 360° preview
    assert engine.refine() == 64 and not engine.done and engine.levels == (32, 64)
    w = engine.settings.weights  # its first level takes the weights of runs with levels (settings.py)
    assert (w.nnfm, w.edges, w.multiscale, w.chroma_tv) == (400.0, 4000.0, 400.0, 6000.0)
    assert "lambda_edges 0 -> 4000" in engine.decisions["level_weights"]
    assert [p.name for p in engine.phases][-2:] == ["refine_0", "finish"]
    widths = set()
    while not engine.done:
        widths.add(engine.step().width)
    assert widths == {64} and engine.current_width == 64 and "64 px" in engine.decisions["levels"]
    assert not torch.equal(engine.c_s, before)  # the level moved the colours, then the final match ran again
    state = engine.state_dict()
    resumed = make_engine(widths=())  # built from the same config (one level fewer): the saved level comes back
    resumed.load_state_dict(state)
    assert resumed.levels == (32, 64) and resumed.done and torch.equal(resumed.c_s, engine.c_s)
    with pytest.raises(ValueError, match="coarse to fine"):
        engine.refine(48)


def test_a_levels_objective_matches_the_painting_at_its_width_within_the_candidate_budget(vgg, no_clip_weights):
    """A finer level's objective resizes the painting for its own width (stroke size × that width) and searches
    among at most ``nnfm_candidates`` of its feature vectors; a crop's objective leaves the large-pattern terms off."""
    from gstyle_core.engine.objective import StyleObjective
    from gstyle_core.engine.phases.refine import CROP_TERMS

    painting = np.random.default_rng(0).uniform(0, 1, (300, 400, 3)).astype(np.float32)
    s = resolve_settings("preview", "360", 4, working_width=64, clip_available=False, nnfm_candidates=0)
    base = StyleObjective(painting, s, vgg=vgg)
    level = StyleObjective(painting, s, vgg=vgg, width=128)
    assert base.target.matrix.shape[1] == 16 * 12 and level.target.matrix.shape[1] == 32 * 24  # 64 / 128 px long
    assert level.loss.weights.multiscale > 0 and level.loss.multiscale_term is not None
    crop = StyleObjective(painting, s, vgg=vgg, width=128, terms=CROP_TERMS)
    assert crop.loss.weights.multiscale == 0 and crop.loss.multiscale_term is None and crop.loss.weights.nnfm > 0
    capped = resolve_settings("preview", "360", 4, working_width=64, clip_available=False, nnfm_candidates=100)
    again = StyleObjective(painting, capped, vgg=vgg, width=128)
    assert again.target.matrix.shape[1] == 100 and "at most 100 of each painting's" in again.style_note
    with pytest.raises(ValueError, match="nnfm_candidates"):
        resolve_settings("preview", "360", 4, nnfm_candidates=-1)
