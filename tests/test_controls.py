"""Every control does what it says (issue #17): options reach the engine, labels say what runs, terms switch."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
import torch
from synthetic import blob_scene

from gstyle_core.io import save_scene
from gstyle_core.style.vgg import CONV_LAYERS, VGGFeatures


@pytest.fixture(scope="module")
def tiny_scene(tmp_path_factory) -> str:
    """A 200-Gaussian scene file (cameras are generated around it)."""
    path = tmp_path_factory.mktemp("scene") / "tiny.ply"
    save_scene(blob_scene(200, seed=1), path)
    return str(path)


@pytest.fixture(scope="module")
def fake_vgg_file(tmp_path_factory) -> tuple[str, dict[str, torch.Tensor]]:
    """A torchvision-layout VGG-16 file (``features.N.weight/bias``) with random values no real file has."""
    gen = torch.Generator().manual_seed(17)
    shapes = {k: v.shape for k, v in VGGFeatures().state_dict().items()}
    state = {f"features.{i}.{kind}": torch.randn(shapes[f"features.{i}.{kind}"], generator=gen) * 0.05
             for i, _ in CONV_LAYERS for kind in ("weight", "bias")}
    path = tmp_path_factory.mktemp("vgg") / "vgg16-fake.pth"
    torch.save(state, path)
    return str(path), state


def assert_vgg_is(vgg, state: dict[str, torch.Tensor]) -> None:
    for i, _ in CONV_LAYERS:
        torch.testing.assert_close(vgg.features[i].weight, state[f"features.{i}.weight"], atol=0, rtol=0)
        torch.testing.assert_close(vgg.features[i].bias, state[f"features.{i}.bias"], atol=0, rtol=0)


# ====================================================================== --vgg-weights
def test_cli_vgg_weights_are_the_ones_loaded(tiny_scene, fake_vgg_file):
    from gstyle_core.cli.stylize import add_stylize_arguments, build_request
    from gstyle_core.engine.build import build_stylizer

    path, state = fake_vgg_file
    parser = argparse.ArgumentParser()
    add_stylize_arguments(parser)
    args = parser.parse_args([tiny_scene, "--vgg-weights", path, "--lambda-clip", "0", "--working-width", "32"])
    engine, *_ = build_stylizer(build_request(args))
    assert engine.settings.to_dict()["vgg_weights"] == path  # recorded in the summary's settings
    assert_vgg_is(engine.build_objective().vgg, state)
    assert engine.decisions["vgg"] == f"VGG-16 weights from {path}"


def test_studio_engine_factory_passes_vgg_weights(tiny_scene, fake_vgg_file):
    from app.engine_factory import make_stylizer

    path, state = fake_vgg_file
    engine = make_stylizer(scene=tiny_scene, vgg_weights=path, lambda_clip=0.0, working_width=32)
    assert engine.settings.vgg_weights == path
    assert_vgg_is(engine.build_objective().vgg, state)
    with pytest.raises(ValueError, match="unknown engine options"):
        make_stylizer(scene=tiny_scene, vgg_weight=path)


def test_studio_command_line_takes_vgg_weights():
    from app.main import build_parser

    args = build_parser().parse_args(["--vgg-weights", "v.pth", "--clip-weights", "c.pt"])
    assert (args.vgg_weights, args.clip_weights) == ("v.pth", "c.pt")



# ====================================================================== terms switch on and off mid-run
@pytest.fixture
def small_engine(no_clip_weights):
    """A tiny real engine on the real StyleObjective (random VGG, no CLIP weights anywhere), built with overrides."""
    from fakes import engine_at_stylize

    torch.manual_seed(0)
    vgg = VGGFeatures().eval()
    style = np.random.default_rng(0).uniform(size=(16, 16, 3)).astype(np.float32)

    def build(**overrides):
        return engine_at_stylize(vgg, blob_scene(150, seed=3), style, **overrides)

    return build


@pytest.mark.parametrize("term", ["nnfm", "clip", "content", "multiscale"])
def test_a_term_that_starts_at_zero_turns_on_mid_run(small_engine, term):
    engine = small_engine(**{f"lambda_{term}": 0.0})
    assert engine.step().losses[term] == 0.0
    engine.set_params(**{f"lambda_{term}": 5.0})
    assert engine.step().losses[term] > 0.0
    assert term in engine.decisions["loss_terms"].split(";")[0]  # "computed: ..."
    if term == "clip":  # built on demand: the coarse substitute, as no CLIP weights exist here
        assert "substitute" in engine.decisions["clip"]
    engine.set_params(**{f"lambda_{term}": 0.0})
    assert engine.step().losses[term] == 0.0


# ====================================================================== the CLIP term says what it is


class StopBeforeStepping(BaseException):
    """Raised instead of the first step (a ``BaseException``, as an interrupt: an ``Exception`` there is a crash,
    which ``gstyle stylize`` words in one line after keeping the run)."""


def test_cli_names_the_coarse_substitute_before_stepping(tiny_scene, tmp_path, monkeypatch, capsys, no_clip_weights):
    from gstyle_core.cli import stylize as cli
    from gstyle_core.style.clip import COARSE_NAME

    def no_steps(engine, *_):
        assert engine.global_step == 0
        raise StopBeforeStepping

    monkeypatch.setattr(cli, "_run_with_progress", no_steps)
    parser = argparse.ArgumentParser()
    cli.add_stylize_arguments(parser)
    args = parser.parse_args([tiny_scene, "--out", str(tmp_path / "o.ply"), "--working-width", "32",
                              "--lambda-clip", "10"])  # on: generated orbits are 360°, where it is off by default
    with pytest.raises(StopBeforeStepping):
        cli.stylize_command(args)
    printed = capsys.readouterr().out
    assert f"CLIP term: {COARSE_NAME} (CLIP ViT-B/32 weights not found" in printed


def test_engine_names_the_clip_term_by_the_weights_found(small_engine, no_clip_weights, tmp_path, monkeypatch):
    from gstyle_core.style import clip as clip_module

    engine = small_engine(lambda_clip=10.0)  # on 360° scenes it is off by default without CLIP weights
    assert engine.clip_name == clip_module.COARSE_NAME and "not found" in engine.decisions["clip"]
    weights = tmp_path / "ViT-B-32.pt"
    weights.write_bytes(b"x")  # only looked up, never loaded, for the name
    monkeypatch.setattr(clip_module, "clip_search_paths", lambda: [weights])
    assert clip_module.clip_term_name() == "CLIP" and clip_module.clip_status() == f"CLIP weights from {weights}"


# ====================================================================== one progress bar with an ETA
class GrowingEngine:
    """Five steps planned; a split at step 3 adds two more (as the real engine's total grows)."""

    clip_name = "coarse (CLIP substitute)"

    def __init__(self) -> None:
        self.global_step, self.planned = 0, 5

    @property
    def done(self) -> bool:
        return self.global_step >= self.planned

    def total_steps(self) -> int:
        return self.planned

    def step(self):
        from gstyle_core.engine.stylizer import StepReport

        self.global_step += 1
        if self.global_step == 3:
            self.planned = 7
        phase = "ground_truth" if self.global_step < 3 else "stylize"
        return StepReport(phase, self.global_step, self.planned, losses={"clip": 0.5, "nnfm": 0.25})


class NoCheckpoints:
    path = "none"
    failures, failed = 0, None  # as RunCheckpointer's when every checkpoint was written

    def after_step(self) -> None:
        pass


def test_stylize_progress_is_one_bar_with_eta_over_the_whole_run(capsys):
    from gstyle_core.cli.stylize import _run_with_progress

    _run_with_progress(GrowingEngine(), NoCheckpoints(), {"stop": False})
    frames = [f for f in capsys.readouterr().err.replace("\n", "\r").split("\r") if f.strip()]
    assert frames[-1].split()[0] == "stylize:" and "100%" in frames[-1] and "7/7" in frames[-1]
    assert "coarse (CLIP substitute)=0.5" in frames[-1]
    assert all("%|" in f and "<" in f for f in frames)  # one bar: percentage and remaining time in every frame
    assert " 0/5 " in frames[0]  # the total planned before the split (tqdm skips frames within 0.1 s)


# ====================================================================== style strength and the structure figure
def _edges_image(seed: int = 0, size: int = 64) -> np.ndarray:
    """Blocks of flat colour (edges between them), on a smooth ramp."""
    rng = np.random.default_rng(seed)
    img = np.repeat(np.linspace(0.2, 0.4, size, dtype=np.float32)[None, :, None], size, 0).repeat(3, 2)
    for _ in range(12):
        y, x, h, w = rng.integers(0, size - 12, 4)
        img[y:y + 4 + h % 12, x:x + 4 + w % 12] = rng.random(3)
    return img


def test_structure_is_one_for_the_same_edges_and_falls_with_foreign_ones():
    from gstyle_core.engine.evaluate import structure_kept

    before = _edges_image()
    alpha = np.zeros(before.shape[:2], np.float32)
    alpha[4:60, 4:60] = 1.0
    assert structure_kept([before], [before], [alpha]) == pytest.approx(1.0)
    assert structure_kept([before], [0.5 * before + 0.3], [alpha]) == pytest.approx(1.0, abs=1e-3)  # colours only
    noise = np.random.default_rng(1).normal(0, 1.0, before.shape).astype(np.float32)
    light, heavy = (structure_kept([before], [before + a * noise], [alpha]) for a in (0.05, 1.0))
    assert 1.0 > light > 0.8 > 0.3 > heavy  # strokes everywhere: edges unrelated to the scene's
    assert abs(structure_kept([before], [_edges_image(seed=7)], [alpha])) < 0.3  # another scene's edges
    assert np.isnan(structure_kept([before], [np.full_like(before, 0.5)], [alpha]))  # no edges left: undefined
    outside = before.copy()
    outside[:2] = np.random.default_rng(2).random((2, 64, 3))  # changes outside the scene do not count
    assert structure_kept([before], [outside], [alpha]) == pytest.approx(1.0)


def test_strength_multiplies_the_style_terms_against_content():
    from gstyle_core.engine.objective import StyleObjective
    from gstyle_core.engine.settings import resolve_settings

    style = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
    torch.manual_seed(0)
    vgg = VGGFeatures()
    weights = {}
    for strength in (1.0, 3.0):
        settings = resolve_settings("preview", "forward", 4, strength=strength, lambda_clip=0.0, working_width=32)
        weights[strength] = StyleObjective(style, settings, vgg=vgg).loss.weights
    assert weights[3.0].nnfm == pytest.approx(3 * weights[1.0].nnfm)
    assert (weights[3.0].content, weights[3.0].tv) == (weights[1.0].content, weights[1.0].tv)
    with pytest.raises(ValueError, match="strength"):
        resolve_settings("preview", "forward", 4, strength=-1.0)


@pytest.mark.slow
def test_cli_records_strength_palette_match_and_prints_structure(tiny_scene, fake_vgg_file, tmp_path, capsys,
                                                                 no_clip_weights):
    import json

    from gstyle_core.cli import stylize as cli

    parser = argparse.ArgumentParser()
    cli.add_stylize_arguments(parser)
    out = tmp_path / "o.ply"
    args = parser.parse_args([tiny_scene, "--out", str(out), "--working-width", "32", "--strength", "2.5",
                              "--vgg-weights", fake_vgg_file[0], "--lambda-clip", "0", "--palette-match", "0.5"])
    assert cli.stylize_command(args) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["settings"]["strength"] == 2.5 and summary["settings"]["defaults"] == "calibrated"
    assert summary["settings"]["palette_match"] == 0.5
    assert -1.0 <= summary["quality"]["structure"] <= 1.0
    printed = capsys.readouterr().out
    assert f"structure kept (edge correlation before/after over the scene): {summary['quality']['structure']:.2f}" \
        in printed
    ts = summary["quality"]["texture_scale"]  # issue #23's figure beside the NNFM drop, which keeps its definition
    assert sum(ts["added"].values()) == pytest.approx(1.0, abs=1e-3)
    assert sum(ts["painting"].values()) == pytest.approx(1.0, abs=1e-3)
    assert ts["painting_side"] > 0 and ts["coarse_ratio"] == pytest.approx(
        ts["added"]["coarse"] / ts["painting"]["coarse"], abs=1e-3)
    assert "texture scale (fine / middle / coarse, DoG" in printed


def test_calibrated_360_run_says_why_the_substitute_is_off(no_clip_weights):
    from synthetic import ring_cameras

    from gstyle_core.engine.objective import StyleObjective
    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer

    torch.manual_seed(0)
    vgg = VGGFeatures().eval()
    style = np.random.default_rng(0).uniform(size=(16, 16, 3)).astype(np.float32)
    settings = resolve_settings("preview", "360", 3, max_views=3, epochs=4, min_steps=0, preprocess_rounds=0,
                                split_rate=0.0, working_width=32)
    engine = Stylizer(blob_scene(150, seed=3), ring_cameras(3), style, settings,
                      objective_factory=lambda s, st: StyleObjective(s, st, vgg=vgg))
    while engine.phase != "stylize":
        engine.step()
    assert settings.weights.clip == 0.0 and "calibrated 360° defaults" in engine.decisions["clip"]
    assert "in CLIP's place" in engine.decisions["broad_strokes"]
    from gstyle_core.engine.controls import CONTROLS
    from gstyle_core.engine.notes import factor_words
    from gstyle_core.style.multiscale import DEFAULT_FACTORS

    words = factor_words(DEFAULT_FACTORS)  # what the run and the panel say is what the term does
    assert f"shrunk {words}," in engine.decisions["broad_strokes"]
    tooltip = next(c.tooltip for c in CONTROLS if c.name == "lambda_multiscale")
    assert f"shrunk {words})" in tooltip  # the panel names the same factors
    report = engine.step()
    assert report.losses["clip"] == 0.0 and report.losses["nnfm"] > 0.0
