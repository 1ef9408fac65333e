"""The live controls' table (issue #22 item 2): every consumer derives from it, so a new control is one row."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from gstyle_core.engine import controls
from gstyle_core.engine.controls import CliOption, Control, Effect, apply_controls, control
from gstyle_core.engine.settings import preset_values, resolve_settings, ui_params


def _write_lr_end(s, value) -> None:
    if not float(value) > 0:
        raise ValueError(f"final lr must be above 0, got {value}")
    s.lr_end = float(value)


# A control that does not exist: the final learning rate, as someone might add it (one row).
LR_END = Control("lr_end", "final learning rate", 0.01, 1e-4, 1.0, True, "Learning rate at the end of the run.",
                 Effect.LR_SCHEDULE, read=lambda s: s.lr_end, write=_write_lr_end,
                 cli=CliOption("learning rate at the end of the run", metavar="LR"))


@pytest.fixture
def with_lr_end(monkeypatch):
    monkeypatch.setattr(controls, "CONTROLS", (*controls.CONTROLS, LR_END))


def _stylize_parser() -> argparse.ArgumentParser:
    from gstyle_core.cli.stylize import add_stylize_arguments

    parser = argparse.ArgumentParser(prog="gstyle stylize")
    add_stylize_arguments(parser)
    return parser


def _engine():
    from gstyle_core.engine.stylizer import Stylizer
    from tests.synthetic import blob_scene, ring_cameras

    settings = resolve_settings("preview", "forward", 3, max_views=3, preprocess_rounds=0, working_width=32)
    return Stylizer(blob_scene(50, seed=2), ring_cameras(3), np.full((8, 8, 3), 0.5, np.float32), settings)


def test_a_new_row_reaches_every_consumer(with_lr_end, capsys):
    from app.panels import PanelState, param_rows
    from tests.fakes import FakeEngine

    parser = _stylize_parser()
    assert parser.parse_args(["--lr-end", "0.003"]).lr_end == 0.003  # the CLI option
    assert parser.parse_args([]).lr_end is None  # not given: the preset's value
    assert "learning rate at the end of the run" in parser.format_help()
    settings = resolve_settings("preview", "forward", 3, lr_end=0.003)  # what build_stylizer passes on
    assert settings.lr_end == 0.003 and ui_params(settings)["lr_end"] == 0.003
    with pytest.raises(ValueError, match="final lr must be above 0"):
        resolve_settings("preview", "forward", 3, lr_end=0.0)
    engine = _engine()
    engine.set_params(lr_end=0.004)  # set_params accepts it
    assert engine.settings.lr_end == 0.004 and engine.current_params()["lr_end"] == 0.004
    rows = {p.key: p for p in param_rows()}  # the panel's slider rows
    assert (rows["lr_end"].label, rows["lr_end"].low, rows["lr_end"].high, rows["lr_end"].log) == (
        "final learning rate", 1e-4, 1.0, True)
    assert PanelState().params["lr_end"] == 0.01
    fake = FakeEngine()
    fake.set_params(lr_end=0.5)  # the test engine accepts the names the table has
    assert fake.params["lr_end"] == 0.5


def test_every_consumer_sees_the_shipped_rows():
    from app.engine_factory import ENGINE_OPTIONS
    from app.engine_host import PAINTING_PARAMS
    from app.panels import param_rows

    names = controls.control_names()
    assert set(ui_params(resolve_settings("preview", "forward", 3))) == set(names)
    parser = _stylize_parser()
    flags = {a.dest: a for a in parser._actions}
    for row in controls.CONTROLS:
        assert (row.name in flags) == (row.cli is not None), row.name
        if row.cli is not None:
            assert flags[row.name].help == row.cli.help and row.name in ENGINE_OPTIONS
    assert [p.key for p in param_rows()] == [r.name for r in controls.CONTROLS
                                             if r.widget == "slider" and not r.with_paintings]
    assert set(PAINTING_PARAMS) == {"style_mix"}
    assert parser.parse_args(["--keep-colours"]).keep_colours is True  # a switch, None when not given


@pytest.mark.parametrize("kind", ["forward", "360"])
@pytest.mark.parametrize("preset", ["preview", "balanced", "final"])
def test_the_table_gives_each_presets_values(preset, kind):
    values = preset_values(preset, kind, 20, clip_available=True)
    s = resolve_settings(preset, kind, 20, clip_available=True)
    assert values["lambda_nnfm"] == s.weights.nnfm and values["lr"] == s.lr_start
    assert values["split_rate"] == s.split_rate and values["keep_colours"] == 0.0 and values["style_mix"] == 0.0
    assert values["lambda_multiscale"] == 0.0  # CLIP keeps its place: no broad-strokes term
    without_clip = preset_values(preset, kind, 20, clip_available=False)
    if kind == "360":  # calibrated 360° defaults without CLIP weights: broad strokes at λ_NNFM, no substitute
        assert without_clip["lambda_multiscale"] == without_clip["lambda_nnfm"] and without_clip["lambda_clip"] == 0.0
    else:  # forward-facing: the paper's values with the substitute either way
        assert without_clip == values
    if (preset, kind) == ("preview", "forward"):  # the rows' own defaults are this preset's (the panel's start),
        # but for the broad-strokes term's: a term's row default is what "on" restores when the preset has it off
        assert values == {row.name: row.default for row in controls.CONTROLS} | {"lambda_multiscale": 0.0}
        assert controls.control("lambda_multiscale").default == values["lambda_nnfm"]


def test_a_change_is_checked_whole_before_anything_changes():
    s = resolve_settings("preview", "forward", 3)
    before = ui_params(s)
    with pytest.raises(ValueError, match="style scale must be a finite number above 0"):
        apply_controls(s, {"lambda_nnfm": 5.0, "strength": 2.0, "style_scale": 0.0})
    with pytest.raises(ValueError, match="unknown parameters: bogus, lambda_bogus"):
        apply_controls(s, {"lambda_nnfm": 5.0, "lambda_bogus": 1.0, "bogus": None})
    with pytest.raises(ValueError, match="strength must be 0 or more, got nan"):
        apply_controls(s, {"lambda_nnfm": 5.0, "strength": float("nan")})
    with pytest.raises(ValueError, match="needs a second style image"):
        apply_controls(s, {"style_mix": 0.5})
    assert ui_params(s) == before


def test_only_what_changed_asks_the_engine_for_work():
    s = resolve_settings("preview", "forward", 3)
    assert apply_controls(s, dict(ui_params(s), style_mix=None)) == Effect.NONE  # the same values: nothing to do
    assert apply_controls(s, {"lambda_nnfm": 5.0, "lr": 0.5}) == Effect.REWEIGHT | Effect.LR_SCHEDULE
    assert (s.weights.nnfm, s.lr_start, s.lr_end) == (5.0, 0.5, pytest.approx(0.05))  # lr_end keeps its ratio
    assert apply_controls(s, {"keep_colours": 1.0}) == control("keep_colours").effects
    assert Effect.RESTORE_CHROMA in control("keep_colours").effects and s.keep_colours is True
    mixed = resolve_settings("preview", "forward", 3, style_weights=(0.5, 0.5))
    assert apply_controls(mixed, {"style_mix": 0.5 + 1e-12}) == Effect.NONE  # float noise of the shares
    assert apply_controls(mixed, {"style_mix": 0.8}) == Effect.STYLE_FEATURES | Effect.CONTENT_TARGETS
    assert mixed.style_weights == pytest.approx((0.2, 0.8)) and ui_params(mixed)["style_mix"] == pytest.approx(0.8)


def test_an_engine_change_is_all_or_nothing():
    engine = _engine()
    with pytest.raises(ValueError, match="style scale"):
        engine.set_params(lambda_nnfm=1.0, style_scale=-1.0)
    assert engine.settings.weights.nnfm == 100.0 and engine.settings.style_scale == 1.0
    engine.set_params(lambda_clip=0.0)
    assert engine.decisions["loss_terms"].startswith("computed: nnfm, content, tv")
