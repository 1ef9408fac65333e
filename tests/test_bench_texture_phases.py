"""``bench/studies/texture_phases.py`` on tiny scenes (seconds): the renders at each phase boundary, the random colour
changes and a whole run from the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from bench_cli import load_bench, tiny_bench_inputs, tiny_engine
from synthetic import blob_scene, ring_cameras


@pytest.fixture(scope="module")
def phases():
    return load_bench("studies/texture_phases")


@pytest.fixture
def style():
    return np.random.default_rng(1).uniform(size=(16, 16, 3)).astype(np.float32)


@pytest.mark.parametrize("final_match", [True, False])
def test_every_stage_is_rendered_and_the_last_is_the_result(phases, vgg, style, final_match):
    scene = blob_scene(150, seed=3, sh_degree=1)
    engine = tiny_engine(vgg, scene, style, colour_match_after=final_match)
    cameras = ring_cameras(2, width=40, height=32)
    images, alphas = phases.stage_renders(engine, scene, cameras)
    assert engine.done
    assert set(images) == set(phases.STAGES)
    assert all(np.array_equal(a, b) for a, b in zip(alphas, phases.render_views(scene, cameras)[1], strict=True))
    result = phases.render_views(engine.stylized_scene(), cameras)[0]
    for got, want in zip(images["final"], result, strict=True):
        assert np.array_equal(got, want)
    # each boundary shows its own scene: the colour match and the stylization each change the renders
    assert not np.allclose(images["preprocessed"][0], images["colour-matched"][0])
    assert not np.allclose(images["colour-matched"][0], images["stylized"][0])
    assert np.array_equal(images["stylized"][0], images["final"][0]) == (not final_match)


def test_a_coarser_random_change_renders_coarser(phases, vgg, style):
    scene = blob_scene(8000, seed=4, spread=0.4, scale=0.02)  # Gaussians of about a pixel in 96-px views
    engine = tiny_engine(vgg, scene, style)  # working width 32: a working-width pixel is 3 of these views'
    cameras = ring_cameras(2, width=96, height=80)
    alphas = phases.render_views(scene, cameras)[1]
    out = phases.random_field_shares(scene, engine, cameras, alphas, [0.0, 4.0])
    per_gaussian, lattice = out["0 px"], out["4 px"]
    for share in (per_gaussian, lattice):
        assert abs(sum(share) - 1) < 1e-9
    assert lattice[2] > per_gaussian[2] + 0.2  # the smooth change puts more of its energy in the coarse band
    assert per_gaussian[0] > lattice[0]


@pytest.mark.slow
def test_command_line_run_writes_the_changes(phases, vgg, no_clip_weights, monkeypatch, tmp_path, style, capsys):
    scene, painting = tiny_bench_inputs(phases, vgg, style, tmp_path, monkeypatch)
    threads = torch.get_num_threads()
    try:
        phases.main([str(scene), "--style", str(painting), "--threads", "1", "--random-field", "0,16",
                     "--json", str(tmp_path / "out.json")])
    finally:
        torch.set_num_threads(threads)
    out = json.loads((tmp_path / "out.json").read_text())
    assert set(out["changes"]) == {"input → preprocessed", "preprocessed → colour-matched",
                                   "colour-matched → stylized", "stylized → final", "colour-matched → final",
                                   "input → final"}
    assert all(len(e) == 3 and min(e) >= 0 for e in out["changes"].values())
    assert set(out["random_field"]) == {"0 px", "16 px"} and len(out["painting"]) == 3
    printed = capsys.readouterr().out
    assert "input → final" in printed and "random change, lattice   16 px" in printed
    assert printed.strip().splitlines()[-1].startswith("RESULT stylization_coarse_ratio=")
