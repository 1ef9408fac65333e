"""The palette match as a control (issue #48 item 5): the final colour match at a strength t from 0 (the colours as
the strokes left them) to 1 (the method's full match), c = (1 − t)·before + t·matched, re-applied at once on a
finished run, kept in checkpoints, on the command line and in the studio's worker."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
import torch
from fakes import MeanColourPull
from synthetic import blob_scene, ring_cameras

from gstyle_core.engine.checkpoint import engine_fingerprint, read_checkpoint, save_checkpoint
from gstyle_core.engine.controls import Effect, apply_controls, control
from gstyle_core.engine.phases.colour_match import ColourMatch, blend_colours, matched_colours, transfer
from gstyle_core.engine.settings import StylizeSettings, check_settings, resolve_settings
from gstyle_core.engine.stylizer import Stylizer


def _style() -> np.ndarray:
    img = np.zeros((8, 8, 3), np.float32)
    img[..., 0], img[::2, :, 2] = 1.0, 0.7
    return img


def _engine(**overrides) -> Stylizer:
    """A tiny real engine (3 ring views, 32 px, no pre-processing or splits) pulled towards a red painting."""
    opts = dict(max_views=3, epochs=2, min_steps=0, preprocess_rounds=0, split_rate=0.0, working_width=32)
    settings = resolve_settings("preview", "forward", 3, **{**opts, **overrides})
    return Stylizer(blob_scene(60, seed=4), ring_cameras(3), _style(), settings, objective_factory=MeanColourPull)


def _finish(engine: Stylizer) -> ColourMatch:
    return next(p for p in engine.phases if isinstance(p, ColourMatch) and p.final)


@pytest.fixture(scope="module")
def finished() -> Stylizer:
    engine = _engine()
    engine.run()
    return engine


def test_the_row_and_its_setting_refuse_what_lies_outside_0_to_1():
    row = control("palette_match")
    assert (row.label, row.low, row.high, row.default, row.log, row.widget) == ("palette match", 0.0, 1.0, 1.0,
                                                                                 False, "slider")
    assert row.effects == Effect.PALETTE_MATCH and "0: the colours as the strokes left them" in row.tooltip
    s = resolve_settings("preview", "forward", 3)
    assert s.palette_match == 1.0
    assert apply_controls(s, {"palette_match": 0.25}) == Effect.PALETTE_MATCH and s.palette_match == 0.25
    for bad in (1.5, -0.1, float("nan"), "much"):
        with pytest.raises(ValueError, match="palette match must"):
            apply_controls(s, {"palette_match": bad})
    assert s.palette_match == 0.25
    assert resolve_settings("preview", "forward", 3, palette_match=0.5).palette_match == 0.5
    with pytest.raises(ValueError, match="palette match must lie from 0"):
        check_settings(StylizeSettings(palette_match=2.0))


def test_the_command_line_takes_it(capsys):
    from gstyle_core.cli.stylize import add_stylize_arguments

    parser = argparse.ArgumentParser(prog="gstyle stylize")
    add_stylize_arguments(parser)
    assert parser.parse_args(["--palette-match", "0.3"]).palette_match == 0.3
    assert parser.parse_args([]).palette_match is None  # not given: the setting's default (1)
    assert "--palette-match T" in parser.format_help()
    with pytest.raises(SystemExit):
        parser.parse_args(["--palette-match", "1.2"])
    assert "palette match must lie from 0 (the strokes' colours) to 1 (the full match), got 1.2" in \
        capsys.readouterr().err


def test_the_blend_is_exact_at_both_ends():
    gen = torch.Generator().manual_seed(0)
    before, matched = torch.rand((40, 3), generator=gen), torch.rand((40, 3), generator=gen)
    assert torch.equal(blend_colours(before, matched, 0.0), before)
    assert torch.equal(blend_colours(before, matched, 1.0), matched)
    assert torch.allclose(blend_colours(before, matched, 0.5), (before + matched) / 2, atol=1e-7)
    assert blend_colours(before, matched, 0.0) is not before  # a copy, never the kept tensor


def test_at_1_the_final_match_is_the_methods_full_match_bit_for_bit():
    engine = _engine()
    while engine.phase != "finish":
        engine.step()
    run, final = engine.run_state, _finish(engine)
    before = run.c_s.detach().clone()
    with torch.no_grad():  # the final match as it was before it had a strength
        A, b = transfer(run, *final.renders())
        full = run.active.keep_unselected(matched_colours(run, before, A, b), before)
    engine.step()
    assert engine.done and torch.equal(engine.c_s, full) and not torch.equal(full, before)
    assert torch.equal(final.before, before) and torch.equal(final.matched, full)


def test_a_finished_run_takes_a_new_strength_at_once(finished):
    final = _finish(finished)
    full, version = finished.c_s.clone(), finished.colour_version
    finished.set_params(palette_match=0.0)
    assert torch.equal(finished.c_s, final.before) and finished.colour_version == version + 1
    finished.set_params(palette_match=0.5)
    assert torch.equal(finished.c_s, torch.lerp(final.before, final.matched, 0.5))
    assert torch.equal(torch.as_tensor(finished.snapshot()["colors"]), finished.c_s.clamp(0, 1))
    finished.set_params(palette_match=1.0)
    assert torch.equal(finished.c_s, full) and finished.colour_version == version + 3
    finished.set_params(palette_match=1.0)  # the same value: nothing to do
    assert finished.colour_version == version + 3


def test_a_run_set_to_0_ends_with_the_colours_the_default_had_before_its_match(finished):
    engine = _engine(palette_match=0.0)
    engine.run()
    assert torch.equal(engine.c_s, _finish(finished).before)  # the run up to the match does not depend on it
    assert torch.equal(_finish(engine).matched, _finish(finished).matched)
    engine.set_params(palette_match=1.0)
    assert torch.equal(engine.c_s, _finish(finished).matched)


def test_a_change_mid_run_applies_when_the_final_match_runs():
    engine = _engine()
    engine.step()
    before, version = engine.c_s.clone(), engine.colour_version
    engine.set_params(palette_match=0.25)
    assert torch.equal(engine.c_s, before) and engine.colour_version == version  # nothing to blend yet
    engine.run()
    final = _finish(engine)
    assert final.applied == 0.25 and torch.equal(engine.c_s, torch.lerp(final.before, final.matched, 0.25))


def test_keep_colours_blends_its_luminance_match():
    engine = _engine(keep_colours=True)
    engine.run()
    final = _finish(engine)
    luma = torch.tensor([0.299, 0.587, 0.114])
    assert not torch.allclose(final.before @ luma, final.matched @ luma, atol=1e-3)  # the match moved luminance
    engine.set_params(palette_match=0.0)
    assert torch.equal(engine.c_s, final.before)
    engine.set_params(palette_match=1.0)
    assert torch.equal(engine.c_s, final.matched)


def test_a_reloaded_finished_run_re_applies_and_an_old_checkpoint_does_not_crash(finished, tmp_path):
    finished.set_params(palette_match=0.3)
    path = save_checkpoint(tmp_path / "run.ckpt", finished.state_dict(), {})
    state, _meta = read_checkpoint(path)
    again = _engine()
    assert engine_fingerprint(again) == engine_fingerprint(finished)  # another strength resumes all the same
    again.load_state_dict(state)  # the engine's own strength (1) is applied at once
    assert again.done and torch.equal(again.c_s, _finish(finished).matched)
    again.set_params(palette_match=0.0)
    assert torch.equal(again.c_s, _finish(finished).before)
    old = _engine(palette_match=0.3)
    for key in ("before", "matched", "applied"):  # written before the palette match was a control
        state["phases"]["finish"].pop(key)
    old.load_state_dict(state)
    shown, version = old.c_s.clone(), old.colour_version
    old.set_params(palette_match=0.0)  # nothing kept to blend: the colours stay, no error
    assert old.done and torch.equal(old.c_s, shown) and old.colour_version == version
    finished.set_params(palette_match=1.0)


def test_colours_changed_since_the_match_are_not_replaced_by_a_stale_blend():
    engine = _engine()
    engine.run()
    engine.set_params(keep_colours=1.0)  # the hues come back at once on the finished run
    kept = engine.c_s.clone()
    engine.set_params(palette_match=0.0)
    assert torch.equal(engine.c_s, kept)
    engine.set_params(keep_colours=0.0)  # the switch back returns the finished colours, at the strength set since
    assert torch.equal(engine.c_s, _finish(engine).before)


def test_a_finer_level_after_the_end_matches_again_at_the_strength_then():
    engine = _engine()
    engine.run()
    engine.refine(64)
    assert not engine.done and _finish(engine).before is None
    engine.set_params(palette_match=0.0)
    engine.run()
    final = _finish(engine)
    assert torch.equal(engine.c_s, final.before) and final.applied == 0.0


def test_the_quality_figures_measure_the_colours_after_the_blend(finished, monkeypatch):
    from gstyle_core.engine.run_figures import evaluate_run, evaluation_cameras
    from gstyle_core.fit.model import scene_from_params
    from gstyle_core.scene import rgb_to_sh_dc
    from gstyle_core.scene_images import render_scene_image
    from gstyle_core.style import vgg as vgg_module

    monkeypatch.setattr(vgg_module, "load_vgg", lambda *a, **k: vgg_module.VGGFeatures().eval())
    full = evaluate_run(finished, finished.input_scene, _style(), width=64)
    finished.set_params(palette_match=0.0)
    try:
        none = evaluate_run(finished, finished.input_scene, _style(), width=64)
    finally:
        finished.set_params(palette_match=1.0)
    unmatched = scene_from_params(finished.params)
    unmatched.sh_dc = rgb_to_sh_dc(_finish(finished).before.clamp(0, 1).numpy())
    expected = np.concatenate([render_scene_image(unmatched, c) for c in evaluation_cameras(finished, 3, 64)], axis=1)
    assert np.array_equal(none["images"][1], expected)  # the "after" renders are the colours shipped at 0
    assert not np.array_equal(full["images"][1], expected)
    assert none["final"]["colour"] > full["final"]["colour"]  # the full match sits closer to the painting's palette
