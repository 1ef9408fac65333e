"""Artist controls (issue #15): keep colours and stroke size, in the engine, the CLI, the summary and checkpoints.

Tiny synthetic scenes and a random VGG (no weights needed): each test runs in seconds on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
import torch
from fakes import engine_at_stylize, random_torchvision_vgg_state
from synthetic import blob_scene

from gstyle_core.engine.objective import MAX_STYLE_SIDE, StyleObjective, style_side
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.io import save_scene
from gstyle_core.scene import rgb_to_sh_dc
from gstyle_core.style.keep_colours import chroma, luminance, luminance_transfer_matrix, with_chroma_of


def warm_scene(n: int = 150, seed: int = 3):
    """Gaussians in oranges, reds and warm browns (hue of the mean chroma: positive I, i.e. red-orange)."""
    scene = blob_scene(n, seed=seed)
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.6, 0.95, n)
    rgb = np.stack([r, r * rng.uniform(0.35, 0.7, n), r * rng.uniform(0.05, 0.3, n)], axis=1)
    scene.sh_dc = rgb_to_sh_dc(rgb).astype(np.float32)
    return scene


def blue_painting(size: int = 48) -> np.ndarray:
    """Blue strokes: diagonal bands of dark and light blue with noise (mean chroma: strongly negative I)."""
    rng = np.random.default_rng(1)
    y, x = np.mgrid[:size, :size]
    band = 0.5 + 0.5 * np.sin((x + y) / 3.0)
    img = np.stack([0.05 + 0.15 * band, 0.15 + 0.35 * band, 0.5 + 0.45 * band], axis=-1)
    return np.clip(img + rng.normal(0, 0.04, img.shape), 0, 1).astype(np.float32)


def textured_painting(size: int = 64) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.uniform(size=(size, size, 3)).astype(np.float32)


@pytest.fixture
def engine_for(vgg, no_clip_weights):
    """A tiny real engine on the real StyleObjective (random VGG, no CLIP weights anywhere), up to stylization."""
    def build(scene=None, style=None, **overrides) -> Stylizer:
        return engine_at_stylize(vgg, warm_scene() if scene is None else scene,
                                 blue_painting() if style is None else style, **{"lambda_clip": 0.0, **overrides})

    return build


def mean_chroma(rgb: np.ndarray) -> np.ndarray:
    return chroma(np.asarray(rgb).reshape(-1, 3)).mean(axis=0)


def covered_luminance(engine: Stylizer, colours: torch.Tensor | None = None) -> np.ndarray:
    """Luminance of the surface (pixel / alpha) where the scene covers the engine's training views (c_s, or
    ``colours``), as the keep-colours colour match measures it."""
    ys = []
    for v in range(len(engine.cameras)):
        image, alpha = engine.render(v, None if colours is None else colours.float()), engine.coverage[v]
        ys.append((luminance(image[alpha > 0.5]) / alpha[alpha > 0.5]).numpy())
    return np.concatenate(ys)


def hue_deg(iq: np.ndarray) -> float:
    return math.degrees(math.atan2(iq[1], iq[0]))


# ====================================================================== keep colours
def test_luminance_helpers_move_colours_along_grey_only():
    rng = np.random.default_rng(0)
    c, s = rng.uniform(0.2, 0.8, (500, 3)), rng.uniform(0, 1, (400, 3)) * [0.2, 0.4, 1.0]
    A, b = luminance_transfer_matrix(c, s)
    mapped = c @ A.T + b
    np.testing.assert_allclose(chroma(mapped), chroma(c), atol=1e-12)  # hue and saturation untouched
    assert luminance(mapped).mean() == pytest.approx(luminance(s).mean())
    assert luminance(mapped).std() == pytest.approx(luminance(s).std())
    out = with_chroma_of(torch.tensor([[0.2, 0.5, 0.9]]), torch.tensor([[0.6, 0.4, 0.2]]))
    assert float(luminance(out)[0]) == pytest.approx(float(luminance(torch.tensor([0.2, 0.5, 0.9]))), abs=1e-6)
    np.testing.assert_allclose(chroma(out.numpy()), chroma(np.array([[0.6, 0.4, 0.2]])), atol=1e-6)


def test_a_warm_scene_stylized_with_a_blue_painting_stays_warm_with_keep_colours(engine_for):
    painting = blue_painting()
    results, renders = {}, {}
    for keep in (False, True):
        engine = engine_for(keep_colours=keep)
        engine.run()
        assert engine.done
        results[keep] = engine.c_s.numpy()
        renders[keep] = covered_luminance(engine)
    renders["input"] = covered_luminance(engine, engine.gt_colours())
    c_in = engine.gt_colours().numpy()
    iq_in, iq_paint = mean_chroma(c_in), mean_chroma(painting)
    iq_keep, iq_plain = mean_chroma(results[True]), mean_chroma(results[False])
    assert iq_in[0] > 0.15 and iq_paint[0] < -0.15  # the inputs are what they claim: warm scene, blue painting
    # keep colours: the result's hue is the scene's, its mean chroma near the scene's and far from the painting's
    # (strokes pushed to very dark or light lose the chroma the RGB cube has no room for: with_chroma_of)
    assert abs(hue_deg(iq_keep) - hue_deg(iq_in)) < 5.0
    assert np.linalg.norm(iq_keep - iq_in) < 0.25 * np.linalg.norm(iq_paint - iq_in)
    iq_out, iq_own = chroma(results[True]), chroma(c_in)  # per Gaussian: its own hue (where it has chroma left)
    coloured = np.linalg.norm(iq_out, axis=1) > 0.02
    assert coloured.mean() > 0.8
    turn = np.degrees(np.abs(np.angle(np.exp(1j * (np.arctan2(iq_out[:, 1], iq_out[:, 0])
                                                  - np.arctan2(iq_own[:, 1], iq_own[:, 0]))))))[coloured]
    assert np.percentile(turn, 95) < 1.0
    # without it the painting's colours arrive (the test fails without the feature)
    assert np.linalg.norm(iq_plain - iq_paint) < 0.25 * np.linalg.norm(iq_paint - iq_in)
    # the luminance is the painting's: the rendered surface's luminance mean and std move to the painting's
    y_paint = luminance(painting.reshape(-1, 3))
    for stat in (np.mean, np.std):
        assert abs(stat(renders[True]) - stat(y_paint)) < 0.5 * abs(stat(renders["input"]) - stat(y_paint))
    assert "kept" in engine.decisions["colours"]


def test_keep_colours_turned_on_mid_run_takes_effect_at_once(engine_for):
    engine = engine_for()
    engine.step()
    objective = engine.build_objective()
    colour_target, content_before = objective.target.matrix.clone(), engine.content_images[0].clone()
    version = engine.colour_version
    engine.set_params(keep_colours=1.0)
    assert engine.colour_version > version  # the studio's worker ships the restored hues without waiting for a step
    c_gt = engine.gt_colours().numpy()
    inside = ((engine.c_s.numpy() > 0.01) & (engine.c_s.numpy() < 0.99)).all(axis=1)
    np.testing.assert_allclose(chroma(engine.c_s.numpy()[inside]), chroma(c_gt[inside]), atol=1e-5)
    assert objective.target.matrix.shape == colour_target.shape and not torch.equal(objective.target.matrix,
                                                                                      colour_target)
    assert not torch.equal(engine.content_images[0], content_before)  # luminance-only match of the content
    assert engine.current_params()["keep_colours"] == 1.0
    engine.step()  # stepping keeps the chroma
    np.testing.assert_allclose(np.median(np.linalg.norm(chroma(engine.c_s.numpy()) - chroma(c_gt), axis=1)), 0,
                               atol=1e-3)
    engine.set_params(keep_colours=0.0)
    assert engine.settings.keep_colours is False and "painting's" in engine.decisions["colours"]


# ====================================================================== stroke size
def test_style_scale_sets_the_size_of_the_style_features(vgg):
    style = textured_painting(96)
    sizes = {}
    for scale in (0.5, 1.0, 2.0):
        settings = resolve_settings("preview", "forward", 3, working_width=64, style_scale=scale, lambda_clip=0.0)
        objective = StyleObjective(style, settings, vgg=vgg)
        sizes[scale] = (tuple(objective._style_small.shape[-2:]), objective.target.matrix.shape[1])
    assert sizes[0.5][0] == (32, 32) and sizes[1.0][0] == (64, 64) and sizes[2.0][0] == (128, 128)
    assert sizes[0.5][1] == 64 and sizes[1.0][1] == 256 and sizes[2.0][1] == 1024  # relu3: a quarter of the side
    assert style_side(256, 1000.0) == (MAX_STYLE_SIDE, True) and style_side(256, 1e-6) == (16, True)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_style_scale_refuses_nonsense(bad, engine_for, capsys):
    from gstyle_core.cli.stylize import add_stylize_arguments

    with pytest.raises(ValueError, match="style scale must be a finite number above 0"):
        resolve_settings("preview", "forward", 3, style_scale=bad)
    parser = argparse.ArgumentParser(prog="gstyle stylize")
    add_stylize_arguments(parser)
    with pytest.raises(SystemExit) as exit_info:
        parser.parse_args(["--style-scale", str(bad)])
    assert exit_info.value.code == 2 and "style scale must be a finite number above 0" in capsys.readouterr().err
    engine = engine_for()
    with pytest.raises(ValueError, match="style scale"):
        engine.set_params(style_scale=bad)
    assert engine.settings.style_scale == 1.0


def test_style_scale_changes_the_result_and_mid_run_re_extracts(engine_for):
    style = textured_painting(64)
    results = {}
    for scale in (0.5, 2.0):
        engine = engine_for(style=style, style_scale=scale, working_width=64, epochs=2, lambda_content=0.0)
        for _ in range(4):
            engine.step()
        results[scale] = engine.c_s.clone()
    assert (results[0.5] - results[2.0]).abs().max() > 1e-3
    engine = engine_for(style=style, style_scale=0.5, working_width=64)
    engine.step()
    before = engine.objective.target.matrix.shape[1]
    engine.set_params(style_scale=2.0)
    assert engine.objective.target.matrix.shape[1] == 16 * before  # 4× the side: 16× the vectors
    assert "128×128 px" in engine.decisions["style_scale"]
    assert engine.step().losses["nnfm"] > 0


def test_a_resumed_engine_keeps_both_controls(engine_for):
    a = engine_for(keep_colours=True, style_scale=2.0)
    a.step()
    state = a.state_dict()
    b = engine_for()
    b.load_state_dict(state)
    assert b.settings.keep_colours is True and b.settings.style_scale == 2.0
    assert b.build_objective().target.matrix.shape == a.objective.target.matrix.shape
    assert b.current_params()["keep_colours"] == 1.0


# ====================================================================== command line and OUT.json
def test_cli_takes_both_controls_and_records_them(tmp_path, no_clip_weights):
    from gstyle_core.cli import stylize as cli
    from gstyle_core.engine.build import build_stylizer

    scene_path, style_path = tmp_path / "warm.ply", tmp_path / "blue.png"
    save_scene(warm_scene(120), scene_path)
    from PIL import Image

    Image.fromarray((blue_painting() * 255).astype(np.uint8)).save(style_path)
    vgg_path = tmp_path / "vgg.pth"
    torch.save(random_torchvision_vgg_state(), vgg_path)
    parser = argparse.ArgumentParser()
    cli.add_stylize_arguments(parser)
    out = tmp_path / "o.ply"
    args = parser.parse_args([str(scene_path), "--style", str(style_path), "--out", str(out), "--working-width", "32",
                              "--keep-colours", "--style-scale", "1.5", "--vgg-weights", str(vgg_path),
                              "--lambda-clip", "0", "--scene-kind", "forward"])
    assert cli.stylize_command(args) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["settings"]["keep_colours"] is True and summary["settings"]["style_scale"] == 1.5
    assert "kept" in summary["decisions"]["colours"] and "stroke size 1.5" in summary["decisions"]["style_scale"]
    plain = build_stylizer(cli.build_request(parser.parse_args([str(scene_path), "--out", str(out)])))[0].settings
    assert plain.keep_colours is False and plain.style_scale == 1.0


# ====================================================================== every control reversible (issue #35)
def _another_value(row) -> float:
    """A value of ``row`` other than its default, inside its range."""
    if row.widget == "checkbox":
        return 1.0 - row.default
    if row.name == "style_mix":  # two paintings: the default is an even mix
        return 0.8
    value = min(row.high, max(row.low, row.default * 2 if row.default else row.high))
    return value if value != row.default else (row.low + row.high) / 2  # a default at the top: the middle


def test_every_control_set_and_unset_on_a_finished_run_gives_the_same_colours_bit_for_bit(engine_for):
    """Ticking and unticking keep colours (and setting any other row of the controls table and setting it back) on a
    finished run returns the colours a viewer shows, and the settings, exactly as they were."""
    from gstyle_core.engine.controls import CONTROLS

    engine = engine_for(style=[blue_painting(), blue_painting()[::-1].copy()])
    engine.run()
    assert engine.done
    for row in CONTROLS:
        before, params = engine.snapshot()["colors"], engine.current_params()
        engine.set_params(**{row.name: _another_value(row)})
        assert engine.current_params()[row.name] != params[row.name], row.name
        if row.name in ("keep_colours", "palette_match"):  # the hues come back, the match is blended again at
            # once: the colours differ while it is set
            assert not np.array_equal(engine.snapshot()["colors"], before)
        engine.set_params(**{row.name: params[row.name]})
        assert engine.current_params() == params, row.name
        assert np.array_equal(engine.snapshot()["colors"], before), row.name


def test_keep_colours_unticked_after_steps_goes_on_with_the_painting(engine_for):
    """After steps on keep colours, unticking cannot return the earlier colours (the steps changed them): the
    painting's colours come back from the next step instead, and the colours are not reset."""
    engine = engine_for()
    engine.set_params(keep_colours=1.0)
    engine.step()
    stepped = engine.c_s.clone()
    engine.set_params(keep_colours=0.0)
    assert torch.equal(engine.c_s, stepped)
