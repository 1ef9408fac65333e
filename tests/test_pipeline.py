"""The step-wise stylization engine: phases, splits, parameters, checkpoints (with a cheap stand-in objective)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from gstyle_core.engine.flat_split import clamp_elongation, flat_split_mask, size_evenness
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from tests.synthetic import blob_scene, ring_cameras


class MeanColourObjective:
    """Pulls the render's mean colour towards the style's mean: cheap, differentiable, counts its calls."""

    def __init__(self, style, settings):
        self.target = torch.as_tensor(style.reshape(-1, 3).mean(0))
        self.calls = 0
        self.weights = settings.weights

    def set_weights(self, weights):
        self.weights = weights

    def __call__(self, image, content, view, coverage=None):
        self.calls += 1
        loss = self.weights.nnfm * ((image.reshape(-1, 3).mean(0) - self.target) ** 2).sum()
        return loss, {"nnfm": float(loss.detach())}


def _engine(**overrides):
    scene = blob_scene(200, seed=3)
    cams = ring_cameras(4)
    style = np.zeros((8, 8, 3), np.float32)
    style[..., 0] = 1.0  # red
    style[::2, :, 2] = 0.5
    opts = dict(max_views=4, epochs=4, min_steps=0, refit_iterations=3, split_at=(0.5,),
                working_width=40, preprocess_rounds=1)
    opts.update(overrides)
    settings = resolve_settings("preview", "forward", 4, **opts)
    return Stylizer(scene, cams, style, settings, objective_factory=MeanColourObjective), scene


def test_settings_follow_the_paper_per_scene_kind():
    ff = resolve_settings("final", "forward", 20)
    s360 = resolve_settings("final", "360", 200, defaults="paper")
    assert (ff.weights.nnfm, s360.weights.nnfm) == (100.0, 10.0)
    assert (ff.weights.clip, ff.weights.content, ff.weights.tv, ff.weights.multiscale) == (10.0, 0.05, 1e-4, 0.0)
    assert (ff.lr_start, ff.lr_end, s360.lr_start, s360.lr_end) == (1e-1, 1e-2, 1e-2, 5e-3)
    # final's budgets are the CPU's (docs/notes/tradeoffs-history.md: the paper's 5/10 rounds of max(5 n, 2000)
    # iterations took 45 of its 68 minutes on the demo): the tiers share the preview's pre-processing and stylization
    # and differ in their finer levels (balanced: 512 px on crops; final: 512 px on whole views, twice the steps, every
    # camera)
    preview, balanced = resolve_settings("preview", "forward", 20), resolve_settings("balanced", "forward", 20)
    for tier in (balanced, ff):
        budget = (tier.preprocess_rounds, tier.refit_iterations, tier.epochs, tier.working_width)
        assert budget == (preview.preprocess_rounds, preview.refit_iterations, preview.epochs, 256) == (1, 60, 4, 256)
    assert (s360.preprocess_rounds, s360.refit_iterations) == (1, 60)
    assert preview.refine_widths == () and balanced.refine_widths == ff.refine_widths == s360.refine_widths == (512,)
    assert (balanced.refine_mode, balanced.refine_epochs, ff.refine_mode, ff.refine_epochs) == ("crops", 2, "whole", 4)
    assert (balanced.max_views, ff.max_views) == (16, 10_000)
    assert ff.split_rate == 0.05 and s360.split_rate == 0.02 and s360.split_at == (0.2, 7 / 15)
    assert resolve_settings("preview", "360", 5, lambda_nnfm=3.0).weights.nnfm == 3.0
    assert replace(resolve_settings("final", "forward", 20, defaults="paper"), defaults="calibrated") == ff  # same
    with pytest.raises(ValueError):
        resolve_settings("nope", "forward", 5)
    with pytest.raises(ValueError):
        resolve_settings("preview", "360", 5, defaults="tuned")


def test_calibrated_360_defaults_and_the_clip_substitute():
    """360° scenes default to the values measured on this machine (settings.CALIBRATED_360); without CLIP weights the
    calibrated 360° defaults turn the coarse CLIP substitute off (unless λ_CLIP is given) and the broad-strokes term
    on at λ_NNFM; the paper's defaults, real CLIP weights and forward-facing scenes have no broad-strokes term."""
    from gstyle_core.engine.settings import CALIBRATED_360

    paper = resolve_settings("preview", "360", 16, defaults="paper", clip_available=False)
    cal = resolve_settings("preview", "360", 16, clip_available=False)
    assert cal.defaults == "calibrated" and cal.weights.nnfm == CALIBRATED_360["nnfm"] != paper.weights.nnfm
    assert (cal.optimizer, cal.view_order, cal.views_per_step) == ("visible_adam", "random", 4)
    assert (paper.optimizer, paper.view_order, paper.views_per_step) == ("adam", "orbit", 1)
    assert cal.weights.clip == 0.0 and paper.weights.clip == 10.0
    assert resolve_settings("preview", "360", 16, clip_available=True).weights.clip == 10.0
    assert resolve_settings("preview", "360", 16, clip_available=False, lambda_clip=2.0).weights.clip == 2.0
    assert cal.working_width == 256 and (cal.epochs, paper.epochs) == (8.0, 4.0)
    assert (resolve_settings("preview", "forward", 16).working_width, resolve_settings("preview", "forward").epochs) \
        == (256, 4.0)
    forward = resolve_settings("preview", "forward", 16, clip_available=False)
    assert (forward.weights.clip, forward.weights.multiscale) == (10.0, 0.0)  # the paper's, with the substitute
    assert cal.weights.multiscale == cal.weights.nnfm and paper.weights.multiscale == 0.0
    with_clip = resolve_settings("preview", "360", 16, clip_available=True)
    assert with_clip.weights.multiscale == 0.0
    tied = resolve_settings("preview", "360", 16, clip_available=False, lambda_nnfm=50.0)
    assert tied.weights.multiscale == 50.0  # the default follows a given λ_NNFM
    given = resolve_settings("preview", "360", 16, clip_available=False, lambda_nnfm=50.0, lambda_multiscale=0.0)
    assert given.weights.multiscale == 0.0  # a given λ_broad strokes wins (0: off)
    assert cal.to_dict()["defaults"] == "calibrated"  # recorded in OUT.json with the other settings


def test_calibrated_360_runs_with_finer_levels_keep_edges():
    """Calibrated 360° runs with finer levels (balanced, final) take λ_edges and a doubled λ_NNFM
    (settings.CALIBRATED_360_LEVELS), the terms tied to λ_NNFM following it; the preview, a run without levels, the
    paper's defaults and forward-facing scenes do not; given values win."""
    from gstyle_core.engine.settings import CALIBRATED_360, CALIBRATED_360_LEVELS

    for preset in ("balanced", "final"):
        w = resolve_settings(preset, "360", 16, clip_available=False).weights
        assert (w.nnfm, w.edges) == (CALIBRATED_360_LEVELS["nnfm"], CALIBRATED_360_LEVELS["edges"])
        assert w.edges > 0 and w.nnfm == 2 * CALIBRATED_360["nnfm"] and w.multiscale == w.nnfm
        assert w.chroma_tv == pytest.approx(w.nnfm * 15.0)
    for settings in (resolve_settings("preview", "360", 16, clip_available=False),
                     resolve_settings("balanced", "360", 16, clip_available=False, refine_widths=()),
                     resolve_settings("balanced", "360", 16, defaults="paper", clip_available=False),
                     resolve_settings("balanced", "forward", 16, clip_available=False)):
        assert settings.weights.edges == 0.0 and settings.weights.nnfm != CALIBRATED_360_LEVELS["nnfm"]
    given = resolve_settings("final", "360", 16, clip_available=False, lambda_nnfm=150.0, lambda_edges=0.0)
    assert (given.weights.nnfm, given.weights.edges, given.weights.multiscale) == (150.0, 0.0, 150.0)


def test_a_previews_first_level_takes_the_weights_of_runs_with_levels():
    """``level_weight_changes``: what a calibrated 360° preview changes when the studio refines it, the same weights
    ``resolve_settings`` gives a run with levels; nothing for weights the artist moved or runs that already have
    levels, forward-facing scenes or the paper's defaults."""
    from gstyle_core.engine.settings import level_weight_changes, ui_params

    with_levels = ui_params(resolve_settings("balanced", "360", 16, clip_available=False))
    changes = level_weight_changes(resolve_settings("preview", "360", 16, clip_available=False))
    assert changes and all(with_levels[k] == v for k, v in changes.items())
    assert set(changes) == {"lambda_nnfm", "lambda_edges", "lambda_multiscale", "lambda_chroma_tv"}
    moved = resolve_settings("preview", "360", 16, clip_available=False, lambda_chroma_tv=100.0)
    assert "lambda_chroma_tv" not in level_weight_changes(moved) and "lambda_nnfm" in level_weight_changes(moved)
    for settings in (resolve_settings("preview", "360", 16, clip_available=False, lambda_nnfm=150.0),
                     resolve_settings("preview", "360", 16, clip_available=False, lambda_edges=10.0),
                     resolve_settings("balanced", "360", 16, clip_available=False),
                     resolve_settings("preview", "forward", 16, clip_available=False),
                     resolve_settings("preview", "360", 16, defaults="paper", clip_available=False)):
        assert level_weight_changes(settings) == {}


def test_flat_split_mask_and_elongation_clamp():
    log_scales = torch.log(torch.full((100, 3), 0.01))
    log_scales[7] = torch.log(torch.tensor([1.0, 1.0, 0.01]))  # one big flat Gaussian
    mask = flat_split_mask(log_scales, gamma=1.0, cap=0.05)
    assert mask.nonzero().flatten().tolist() == [7]
    assert size_evenness(log_scales, 1.0)["flat_fraction"] == pytest.approx(0.01)
    ls = torch.log(torch.tensor([[3.0, 1.0, 0.5], [1.2, 1.0, 1.0]]))
    assert clamp_elongation(ls, 1.5) == 1
    assert torch.allclose(torch.exp(ls[0]), torch.tensor([2.0, 1.0, 0.5]))
    assert torch.allclose(torch.exp(ls[1]), torch.tensor([1.2, 1.0, 1.0]))


def test_engine_runs_all_phases_and_splits_by_colour_gradient():
    eng, scene = _engine()
    phases = []
    reports = []
    while not eng.done:
        r = eng.step()
        reports.append(r)
        if not phases or phases[-1] != r.phase:
            phases.append(r.phase)
        assert len(reports) < 500
    assert phases == ["ground_truth", "preprocess", "colour_match", "stylize", "refit", "stylize", "finish"]
    assert eng.gaussian_count > scene.count  # pre-processing and colour-gradient splits added Gaussians
    assert any(r.geometry_changed for r in reports if r.phase == "refit")
    snap = eng.snapshot()
    assert snap["colors"].shape == (eng.gaussian_count, 3) and np.isfinite(snap["colors"]).all()
    assert snap["colors"].min() >= 0 and snap["colors"].max() <= 1
    # the stand-in objective pulls towards red: the stylized scene is redder than the original
    assert snap["colors"][:, 0].mean() > snap["colors"][:, 1].mean()
    out = eng.stylized_scene()
    assert out.count == eng.gaussian_count and out.sh_degree == 0


def test_set_params_takes_effect_on_next_step():
    eng, _ = _engine(preprocess_rounds=0)
    while eng.phase != "stylize":
        eng.step()
    eng.step()
    eng.set_params(lambda_nnfm=0.0, lr=0.5)
    assert eng.objective.weights.nnfm == 0.0
    r = eng.step()
    assert r.losses["nnfm"] == 0.0
    assert eng.stylize.optimiser.param_groups[0]["lr"] <= 0.5
    with pytest.raises(ValueError):
        eng.set_params(lambda_bogus=1.0)
    assert eng.current_params()["lambda_nnfm"] == 0.0 and eng.current_params()["lr"] == 0.5


def test_zero_split_rate_never_splits():
    eng, scene = _engine(preprocess_rounds=0, split_rate=0.0)
    eng.run()
    assert eng.gaussian_count == scene.count


@pytest.mark.parametrize("preset", ["preview", "balanced", "final"])
@pytest.mark.parametrize("kind", ["forward", "360"])
def test_every_preset_splits_and_the_split_rate_changes_the_result(preset, kind):
    """Splits sit at fractions of the stylization, so the preset's own step count (and views per step) keeps them."""
    counts = {}
    for rate in (0.05, 0.2):
        settings = resolve_settings(preset, kind, 4, split_rate=rate, preprocess_rounds=0, refit_iterations=1,
                                    working_width=32, min_steps=0, epochs=3.0)
        eng = Stylizer(blob_scene(200, seed=3), ring_cameras(4), np.ones((8, 8, 3), np.float32), settings,
                       objective_factory=MeanColourObjective)
        assert eng.split_steps, f"{preset}/{kind}: no split planned in {eng.stylize_steps} steps"
        eng.run()
        counts[rate] = eng.gaussian_count
    assert counts[0.2] > counts[0.05] > 200


def test_planned_total_stays_put_through_splits_and_checkpoints():
    """The progress total counts performed splits and their refits: it never shrinks, and the run ends on it."""
    settings = resolve_settings("preview", "forward", 4, split_rate=0.1, preprocess_rounds=0, refit_iterations=2,
                                working_width=32, min_steps=0, epochs=3.0, split_at=(0.3, 0.6))
    eng = Stylizer(blob_scene(120, seed=5), ring_cameras(4), np.ones((8, 8, 3), np.float32), settings,
                   objective_factory=MeanColourObjective)
    planned = eng.total_steps()
    assert len(eng.split_steps) == 2
    seen_totals = set()
    while not eng.done:
        rep = eng.step()
        seen_totals.add(rep.total_steps)
        if eng.splits_done == 1 and eng.phase == "stylize":
            resumed = Stylizer(blob_scene(120, seed=5), ring_cameras(4), np.ones((8, 8, 3), np.float32),
                               settings, objective_factory=MeanColourObjective)
            resumed.load_state_dict(eng.state_dict())
            assert resumed.total_steps() == planned
    assert eng.splits_done == 2
    assert seen_totals == {planned} and eng.global_step == planned


def test_split_steps_count_optimiser_steps_with_several_views_per_step():
    settings = resolve_settings("preview", "forward", 4, working_width=32, min_steps=0, epochs=8.0,
                                views_per_step=4, split_at=(0.5,), grad_accumulate_from=0.25)
    eng = Stylizer(blob_scene(50, seed=1), ring_cameras(4), np.ones((8, 8, 3), np.float32), settings,
                   objective_factory=MeanColourObjective)
    assert eng.stylize_steps == 8 and eng.split_steps == [4] and eng.stylize.accumulate_from == 2


def test_colour_split_takes_the_gaussians_with_the_largest_accumulated_gradient(monkeypatch):
    eng, _ = _engine(preprocess_rounds=0, split_rate=0.1)
    while not (eng.phase == "stylize" and eng.stylize.step_index in eng.split_steps):
        eng.step()
    acc = eng.run_state.grad_acc.clone()
    assert acc.max() > 0
    seen = {}
    real_split = eng.run_state.split

    def spy(mask, *args, **kwargs):
        seen["mask"] = mask.clone()
        return real_split(mask, *args, **kwargs)

    monkeypatch.setattr(eng.run_state, "split", spy)
    eng.step()
    ids = eng.active.seen_ids()
    pool = acc if ids is None else acc[ids]
    k = int(0.1 * len(pool))
    chosen = acc[seen["mask"]]
    assert int(seen["mask"].sum()) == k
    assert chosen.min() >= torch.topk(pool, k).values.min()  # none outside the top k by ‖∂L/∂c_s‖
    assert chosen.min() > pool.median()


def test_checkpoint_resume_matches_uninterrupted_run():
    a, _ = _engine(preprocess_rounds=0)
    for _ in range(8):
        a.step()
    state = a.state_dict()
    b, _ = _engine(preprocess_rounds=0)
    b.load_state_dict(state)
    a.run()
    b.run()
    assert a.gaussian_count == b.gaussian_count
    assert np.allclose(a.snapshot()["colors"], b.snapshot()["colors"], atol=1e-5)


def test_content_targets_are_what_the_colour_matched_gaussians_render():
    # Ground truth rendered from the scene (no photos): the background must stay black in the content targets, and
    # where no colour clips, the target equals the render of the colour-matched c_s (render linear in colours).
    style = np.random.default_rng(0).uniform(0.3, 0.6, (16, 16, 3)).astype(np.float32)  # mild: little clipping
    scene = blob_scene(200, seed=3)
    settings = resolve_settings("preview", "forward", 4, max_views=4, working_width=40, preprocess_rounds=0,
                                match_detail_px=0.0)  # whole colours mapped (test_speckle.py: the detail-keeping one)
    eng = Stylizer(scene, ring_cameras(4), style, settings, objective_factory=MeanColourObjective)
    while eng.phase != "stylize":
        eng.step()
    A, b = eng.colour_transform
    assert np.all((eng.gt_colours().numpy() @ A.T + b >= 0) & (eng.gt_colours().numpy() @ A.T + b <= 1))  # no clipping
    for view, (target, alpha) in enumerate(zip(eng.content_images, eng.coverage, strict=True)):
        with torch.no_grad():
            render = eng.render(view)
        assert float((render - target).abs().max()) < 1e-4
        assert bool((alpha < 1e-6).any())
        assert float(target[alpha < 1e-6].abs().max()) == 0.0  # uncovered background stays black


def test_raster_backend_setting_reaches_ground_truth_and_refits_with_the_same_result(monkeypatch):
    """Both backends serve every ground-truth render and refit iteration, and agree where the arithmetic is
    deterministic: the ground-truth images and the refit loss's gradients at one state. (Not the means after a
    100-iteration Adam trajectory: Adam moves a parameter by about lr whatever its gradient's size, so gradients
    of 1e-11 whose sign depends on float32 summation order move the means apart differently on different CPUs.)"""
    import gstyle_core.engine.phases.ground_truth as ground_truth_module
    import gstyle_core.fit.trainer as trainer_module
    from gstyle_core.fit.model import params_from_scene, render_params
    from gstyle_core.fit.ssim import ssim

    used: list[str] = []
    for module in (ground_truth_module, trainer_module):
        original = module.render_params

        def recording(*args, _original=original, **kw):
            used.append(kw.get("backend", "fast"))
            return _original(*args, **kw)

        monkeypatch.setattr(module, "render_params", recording)
    gt, grads = {}, {}
    for backend in ("fast", "reference"):
        used.clear()
        eng, scene = _engine(raster_backend=backend, force_preprocess=True)
        while eng.phase != "stylize":
            eng.step()
        assert used and set(used) == {backend}  # every ground-truth render and refit iteration
        gt[backend] = torch.stack(eng.gt_images)
        # one refit loss (0.8 L1 + 0.2 D-SSIM, as the Trainer's) at the input's state against a grey target whose
        # residuals are far from 0, so no L1 sign depends on rounding
        params = params_from_scene(scene.with_sh_degree(0))
        out = render_params(params, eng.cameras[0], sh_degree=0, backend=backend)
        target = torch.full_like(out.image, 0.5)
        loss = 0.8 * (out.image - target).abs().mean() + 0.2 * (1 - ssim(out.image, target))
        loss.backward()
        grads[backend] = {k: v.grad.clone() for k, v in params.items() if v.grad is not None and v.numel()}
    # float32 rounding: one ulp is 2^-24 of a value; sums over the few hundred Gaussians a pixel blends, in another
    # order per backend, stay within a few hundred ulps of the largest term
    eps = torch.finfo(torch.float32).eps
    assert torch.allclose(gt["fast"], gt["reference"], rtol=0, atol=512 * eps)
    assert grads["fast"].keys() == grads["reference"].keys() and "means" in grads["fast"]
    for name, g in grads["fast"].items():
        tol = 1024 * eps * float(g.abs().max())
        assert torch.allclose(g, grads["reference"][name], rtol=0, atol=tol), name
    with pytest.raises(ValueError, match="raster backend"):
        resolve_settings("preview", "forward", 4, raster_backend="opengl")


def test_forward_children_keep_the_parents_footprint():
    """The CPU tiers' short refits cannot regrow children at the reference's 1/16 scale
    (docs/notes/tradeoffs-history.md and docs/notes/tradeoffs.md: fern); forward-facing balanced stylizes on the
    preview's budget before its finer level."""
    assert resolve_settings("preview", "forward", 20).split_scale_divisor == 1.6
    assert resolve_settings("preview", "forward", 20, defaults="paper").split_scale_divisor == 1.6
    assert resolve_settings("balanced", "forward", 20).split_scale_divisor == 1.6  # 140 refit iterations
    assert resolve_settings("final", "forward", 20).split_scale_divisor == 1.6  # 300
    assert resolve_settings("balanced", "forward", 20, defaults="paper").split_scale_divisor == 1.6
    assert resolve_settings("preview", "360", 20).split_scale_divisor == 8.0
    forward = [resolve_settings(preset, "forward", 20) for preset in ("preview", "balanced")]
    assert [(s.epochs, s.min_steps, s.working_width) for s in forward] == [(4.0, 30, 256)] * 2
    assert forward[1].refine_widths == (512,) and resolve_settings("balanced", "360", 20).epochs == 8.0
