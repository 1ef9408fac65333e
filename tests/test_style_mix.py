"""Two paintings mixed (issue #15, item 3): weights, the weighted palette, every style term as the weighted sum of
its terms, the engine mid-run and resumed, the CLI and OUT.json.

Tiny synthetic scenes and a random VGG (no weights needed)."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
import torch
from fakes import engine_at_stylize, random_torchvision_vgg_state
from synthetic import blob_scene

from gstyle_core.engine.phases.colour_match import surface_pixels
from gstyle_core.engine.settings import resolve_settings, ui_params
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.errors import GStyleError
from gstyle_core.style import nnfm as nnfm_module
from gstyle_core.style.clip import CoarseStyleLoss
from gstyle_core.style.colour_match import Palette, apply_colour_transform, colour_transfer_matrix
from gstyle_core.style.keep_colours import luminance, luminance_transfer_matrix
from gstyle_core.style.losses import StyleLoss
from gstyle_core.style.mix import normalise_style_weights, parse_style_weights, weights_with_mix
from gstyle_core.style.nnfm import StyleTarget, WeightedTargets


def painting(colour: tuple[float, float, float], seed: int, size: int = 48) -> np.ndarray:
    """Strokes around one colour: diagonal bands with noise."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[:size, :size]
    band = (0.5 + 0.5 * np.sin((x + 2 * y) / (2.0 + seed)))[..., None]
    img = np.asarray(colour) * (0.4 + 0.6 * band) + rng.normal(0, 0.05, (size, size, 3))
    return np.clip(img, 0, 1).astype(np.float32)


BLUE, RED = painting((0.2, 0.35, 0.9), 1), painting((0.9, 0.25, 0.15), 2)


@pytest.fixture
def engine_for(vgg, no_clip_weights):
    """A tiny real engine on the real StyleObjective (random VGG, no CLIP weights), up to stylization."""
    def build(styles=(BLUE, RED), **overrides) -> Stylizer:
        style = styles[0] if len(styles) == 1 else list(styles)
        return engine_at_stylize(vgg, blob_scene(150, seed=3), style, **{"lambda_clip": 0.0, **overrides})

    return build


# ====================================================================== weights and the weighted palette
def test_weights_are_checked_and_normalised():
    assert normalise_style_weights([0.7, 0.3], 2) == pytest.approx((0.7, 0.3))
    assert normalise_style_weights([7, 3], 2) == pytest.approx((0.7, 0.3))
    assert normalise_style_weights(None, 3) == pytest.approx((1 / 3,) * 3)
    for bad, why in (([0.5], "1 style weight"), ([1, -1], "0 or more"), ([0, 0], "not all be 0"),
                     ([float("nan"), 1], "finite")):
        with pytest.raises(ValueError, match=why):
            normalise_style_weights(bad, 2)
    with pytest.raises(ValueError, match="0.7,0.3"):
        parse_style_weights("0.7;0.3")
    assert weights_with_mix((0.7, 0.3), 0.8) == pytest.approx((0.2, 0.8))
    assert weights_with_mix((0.2, 0.2, 0.6), 0.5) == pytest.approx((0.25, 0.25, 0.5))
    with pytest.raises(ValueError, match="between 0 and 1"):
        weights_with_mix((0.5, 0.5), 1.5)


def test_the_weighted_palette_is_the_palette_of_the_pooled_pixels():
    rng = np.random.default_rng(0)
    a, b = rng.uniform(0, 0.5, (300, 3)), rng.uniform(0.3, 1, (100, 3))
    mixed = Palette.mixture([Palette.of(a), Palette.of(b)], [3, 1])  # shares as the pixel counts
    pooled = Palette.of(np.concatenate([a, b]))
    np.testing.assert_allclose(mixed.mean, pooled.mean, atol=1e-12)
    np.testing.assert_allclose(mixed.cov, pooled.cov, atol=1e-12)
    only_a = Palette.mixture([Palette.of(a), Palette.of(b)], [1, 0])
    np.testing.assert_allclose(only_a.cov, Palette.of(a).cov, atol=1e-12)
    # the colour match maps content onto the mixture's mean and covariance
    content = rng.uniform(0, 1, (500, 3))
    mapped = apply_colour_transform(content, *colour_transfer_matrix(content, mixed), clip=False).astype(np.float64)
    np.testing.assert_allclose(mapped.mean(0), mixed.mean, atol=1e-5)
    np.testing.assert_allclose(np.cov(mapped, rowvar=False, bias=True), mixed.cov, atol=1e-5)
    # keep colours: the luminance map takes the mixture's luminance mean and std
    y = luminance(apply_colour_transform(content, *luminance_transfer_matrix(content, mixed), clip=False))
    pooled_y = luminance(np.concatenate([a, b]))
    assert float(y.mean()) == pytest.approx(float(pooled_y.mean()), abs=1e-5)
    assert float(y.std()) == pytest.approx(float(pooled_y.std()), abs=1e-5)


# ====================================================================== every style term as a weighted sum
def test_nnfm_of_a_mix_is_the_weighted_sum_and_skips_weight_zero(vgg, monkeypatch):
    targets = [StyleTarget.from_image(vgg, torch.as_tensor(s).permute(2, 0, 1)[None]) for s in (BLUE, RED)]
    render = torch.rand(1, 3, 32, 32)
    single = [float(StyleLoss(vgg, t, weights={"clip": 0, "content": 0, "tv": 0})(render)[1]["nnfm"])
              for t in targets]
    mix = WeightedTargets(targets, (0.7, 0.3))
    mixed = StyleLoss(vgg, mix, weights={"clip": 0, "content": 0, "tv": 0})
    assert mixed(render)[1]["nnfm"] == pytest.approx(0.7 * single[0] + 0.3 * single[1], rel=1e-5)
    calls = []
    original = nnfm_module.nnfm_loss
    monkeypatch.setattr(nnfm_module, "nnfm_loss", lambda *a, **k: calls.append(1) or original(*a, **k))
    mix.weights = (1.0, 0.0)
    assert mixed(render)[1]["nnfm"] == pytest.approx(single[0], rel=1e-5)
    assert len(calls) == 1  # the painting of weight 0 is not searched


def test_the_coarse_clip_substitute_of_a_mix_is_the_weighted_sum(vgg):
    blue, red = (torch.as_tensor(s).permute(2, 0, 1)[None] for s in (BLUE, RED))
    render = torch.rand(1, 3, 64, 64)
    single = [float(CoarseStyleLoss(vgg, s)(render)) for s in (blue, red)]
    mixed = CoarseStyleLoss(vgg, [blue, red], style_weights=(0.25, 0.75))
    assert float(mixed(render)) == pytest.approx(0.25 * single[0] + 0.75 * single[1], rel=1e-5)
    mixed.set_style_weights((0.0, 1.0))
    assert float(mixed(render)) == pytest.approx(single[1], rel=1e-5)


def test_the_clip_term_of_a_mix_is_the_weighted_sum():
    from gstyle_core.style.clip import ClipStyleLoss, ClipVisionEncoder

    torch.manual_seed(0)
    encoder = ClipVisionEncoder(image_size=64, patch_size=16, width=64, layers=1, heads=2, output_dim=32)
    blue, red = (torch.as_tensor(s).permute(2, 0, 1)[None] for s in (BLUE, RED))
    render = torch.rand(1, 3, 80, 80)

    def term(style, weights=None):
        return ClipStyleLoss(encoder, style, n_crops=4, generator=torch.Generator().manual_seed(1),
                             style_weights=weights)

    single = [float(term(s)(render)) for s in (blue, red)]
    assert float(term([blue, red], (0.6, 0.4))(render)) == pytest.approx(0.6 * single[0] + 0.4 * single[1], rel=1e-5)


# ====================================================================== the engine
def test_the_engine_matches_colours_to_the_weighted_palette(engine_for):
    engine = engine_for(style_weights=(0.7, 0.3))
    assert engine.settings.style_weights == pytest.approx((0.7, 0.3))
    mixture = Palette.mixture([Palette.of(BLUE), Palette.of(RED)], (0.7, 0.3))
    A, b = engine.colour_transform
    expected = colour_transfer_matrix(np.zeros((1, 3)) + 0.5, mixture)  # same style side; content differs
    keep = engine.settings.keep_colours
    gt = torch.cat([surface_pixels(g, m, keep) for g, m in zip(engine.gt_images, engine.coverage, strict=True)]).numpy()
    mapped = apply_colour_transform(gt, A, b, clip=False).astype(np.float64)
    np.testing.assert_allclose(mapped.mean(0), mixture.mean, atol=1e-4)
    assert not np.allclose(A, expected[0])  # (a sanity check that the content side is the scene's)
    assert "2 paintings mixed 0.70 / 0.30" in engine.decisions["styles"]
    blue_only = engine_for(style_weights=(1.0, 0.0))
    one = engine_for(styles=(BLUE,))
    np.testing.assert_allclose(blue_only.c_s.numpy(), one.c_s.numpy(), atol=1e-5)


def test_the_mix_moves_the_result_towards_the_heavier_painting(engine_for, vgg):
    from gstyle_core.engine.evaluate import Evaluator

    ev = Evaluator(vgg, [BLUE, RED], width=32, weights=(0.5, 0.5))
    distances = {}
    for mix in (0.1, 0.9):
        engine = engine_for(style_weights=(1 - mix, mix), epochs=6, lambda_content=0.0)
        while not engine.done:
            engine.step()
        renders = [engine.render(v).numpy() for v in range(len(engine.cameras))]
        distances[mix] = ev.measure(renders, renders)["nnfm_styles"]
    # more red weight: closer to the red painting, further from the blue one
    assert distances[0.9][1] < distances[0.1][1]
    assert distances[0.9][0] > distances[0.1][0]


def test_the_mix_changes_mid_run_and_survives_a_resume(engine_for):
    engine = engine_for(style_weights=(0.7, 0.3))
    engine.step()
    content_before = engine.content_images[0].clone()
    engine.set_params(style_mix=0.9)
    assert engine.settings.style_weights == pytest.approx((0.1, 0.9))
    assert engine.current_params()["style_mix"] == pytest.approx(0.9)
    assert engine.objective.target.weights == pytest.approx((0.1, 0.9))
    assert not torch.equal(engine.content_images[0], content_before)  # content targets re-matched to the palette
    assert "0.10 / 0.90" in engine.decisions["styles"] and "0.10 / 0.90" in engine.decisions["style_scale"]
    assert engine.step().losses["nnfm"] > 0
    state = engine.state_dict()
    resumed = engine_for(style_weights=(0.5, 0.5))
    resumed.load_state_dict(state)
    assert resumed.settings.style_weights == pytest.approx((0.1, 0.9))
    assert resumed.build_objective().target.weights == pytest.approx((0.1, 0.9))
    with pytest.raises(ValueError, match="second style image"):
        engine_for(styles=(BLUE,)).set_params(style_mix=0.5)


def test_ui_params_show_the_mix():
    settings = resolve_settings("preview", "forward", 3, style_weights=(0.7, 0.3))
    assert ui_params(settings)["style_mix"] == pytest.approx(0.3)
    assert ui_params(resolve_settings("preview", "forward", 3))["style_mix"] == 0.0


# ====================================================================== command line and OUT.json
def _save_png(path, img):
    from PIL import Image

    Image.fromarray((img * 255).astype(np.uint8)).save(path)


@pytest.mark.slow
def test_cli_mixes_two_styles_and_names_them_with_weights(tmp_path, no_clip_weights):
    from gstyle_core.cli import stylize as cli
    from gstyle_core.io import save_scene

    scene_path, blue_path, red_path = tmp_path / "s.ply", tmp_path / "blue.png", tmp_path / "red.png"
    save_scene(blob_scene(120, seed=3), scene_path)
    _save_png(blue_path, BLUE)
    _save_png(red_path, RED)
    vgg_path = tmp_path / "vgg.pth"
    torch.save(random_torchvision_vgg_state(), vgg_path)
    parser = argparse.ArgumentParser()
    cli.add_stylize_arguments(parser)
    out = tmp_path / "o.ply"
    common = [str(scene_path), "--style", str(blue_path), "--style", str(red_path), "--out", str(out),
              "--working-width", "32", "--vgg-weights", str(vgg_path), "--lambda-clip", "0", "--scene-kind", "forward"]
    with pytest.raises(GStyleError, match="3 style weight"):
        cli.stylize_command(parser.parse_args(common + ["--style-weights", "0.5,0.3,0.2"]))
    assert not out.exists()
    assert cli.stylize_command(parser.parse_args(common + ["--style-weights", "0.7,0.3"])) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert [s["path"] for s in summary["styles"]] == [str(blue_path), str(red_path)]
    assert [s["weight"] for s in summary["styles"]] == pytest.approx([0.7, 0.3])
    assert "2 paintings mixed" in summary["decisions"]["styles"]
    assert len(summary["quality"]["final"]["nnfm_styles"]) == 2
    with pytest.raises(SystemExit):
        parser.parse_args(common + ["--style-weights", "a,b"])

