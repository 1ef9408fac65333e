"""``bench/studies/scale_causes.py`` and ``bench/studies/scale_step.py`` against the engine's public API, on tiny scenes
(seconds): the optimiser patches, a whole run from the command line, and both dissection modes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from bench_cli import load_bench, tiny_bench_inputs
from fakes import engine_at_stylize
from synthetic import blob_scene


@pytest.fixture(scope="module")
def causes():
    return load_bench("studies/scale_causes")


@pytest.fixture(scope="module")
def step_bench():
    return load_bench("studies/scale_step")


@pytest.fixture
def style():
    return np.random.default_rng(1).uniform(size=(16, 16, 3)).astype(np.float32)


@pytest.mark.parametrize(("optim", "kind"), [("global", "GlobalNormAdam"), ("eps", "FirstRmsEpsAdam")])
def test_patched_optimiser_starts_the_variant_and_steps(causes, vgg, style, optim, kind):
    engine = engine_at_stylize(vgg, blob_scene(150, seed=3), style)
    notes = causes.patch_optimiser(engine, optim, coherent_px=2.0)
    before = engine.c_s.clone()
    engine.step()
    opt = engine.stylize.optimiser
    assert type(opt).__name__ == kind
    assert opt.param is engine.stylize.c_opt
    assert opt.step.__name__ == "smoothed_step"  # the gradient diffused over neighbours first
    assert notes["passes"] >= 1 and len(notes["neighbour_seconds"]) == 1
    assert not torch.equal(before, engine.c_s)


@pytest.mark.slow
def test_command_line_run_writes_the_row(causes, vgg, no_clip_weights, monkeypatch, tmp_path, style):
    """Parse, build (the tiny scene file through ``build_request``), run with a patch and the broad-strokes term at
    the given λ, and write OUT.json with the table's figures."""
    scene, painting = tiny_bench_inputs(causes, vgg, style, tmp_path, monkeypatch)
    threads = torch.get_num_threads()
    try:
        causes.main([str(scene), "--style", str(painting), "--tag", "t", "--out-dir", str(tmp_path),
                     "--optim", "eps", "--multiscale", "30", "--seed", "1", "--threads", "1"])
    finally:
        torch.set_num_threads(threads)
    out = json.loads((tmp_path / "t.json").read_text())
    assert out["settings"]["weights"]["multiscale"] == 30.0 and out["settings"]["seed"] == 1
    assert out["variant"]["optim"] == "eps" and out["multiscale_seconds"] >= 0
    assert math.isfinite(out["nnfm_drop"]) and math.isfinite(out["structure"])
    assert set(out["texture_scale"]) >= {"added", "painting"}
    assert out["stylize_steps"] >= 1 and (tmp_path / "t_after.png").exists()


def test_multiscale_and_lambda_multiscale_must_agree(causes, capsys):
    with pytest.raises(SystemExit):
        causes.main(["--tag", "x", "--multiscale", "1", "--lambda-multiscale", "2"])
    assert "give one" in capsys.readouterr().err


def test_spectrum_and_time(step_bench, vgg, style, monkeypatch, capsys):
    engine = engine_at_stylize(vgg, blob_scene(150, seed=3), style)
    monkeypatch.setattr(step_bench, "engine_at_stylize", lambda args: engine)
    weights = engine.settings.weights
    rows = step_bench.spectrum(None, [0, 1], [1.0])
    assert [r["term"] for r in rows] == ["nnfm", "content", "tv", "multiscale"]
    for row in rows:
        for kind in step_bench.KINDS:
            assert len(row[kind]) == 3 and abs(sum(row[kind]) - 1) < 0.01
    assert engine.build_objective().loss.multiscale_term is not None  # built on demand
    out = step_bench.step_time(None, rounds=2, weight=None)
    assert out["nnfm"] > 0 and out["nnfm+multiscale"] > 0 and out["ratio"] > 0
    assert out["lambda_multiscale"] == (weights.multiscale or weights.nnfm)
    assert engine.settings.weights == weights
    assert len(capsys.readouterr().out.strip().splitlines()) == 5
