"""``bench/studies/final_match_cost.py`` on tiny scenes (seconds): the figures without the final colour match and with
it, all from the same colours, and the command line."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from bench_cli import load_bench, tiny_bench_inputs, tiny_engine
from synthetic import blob_scene


@pytest.fixture(scope="module")
def cost():
    return load_bench("studies/final_match_cost")


@pytest.fixture
def style():
    """A painting far more colourful and darker than the blob scene, so that a colour match has work to do."""
    rng = np.random.default_rng(1)
    return (rng.uniform(size=(16, 16, 3)) * np.array([0.9, 0.3, 0.6])).astype(np.float32)


def test_each_row_starts_from_the_same_colours_and_the_match_brings_the_palette(cost, vgg, style):
    scene = blob_scene(150, seed=3)
    engine = tiny_engine(vgg, scene, style)
    detail_px = engine.settings.match_detail_px
    cost.step_to_final_match(engine)
    assert engine.current_phase().name == "finish"
    start = engine.run_state.c_s.clone()
    figures = cost.Figures(engine, scene, style, [32])
    rows = cost.match_rows(engine, figures, [0.0, 4.0])
    assert [r["detail_px"] for r in rows] == [None, 0.0, 4.0]
    assert torch.equal(engine.run_state.c_s, start) and engine.settings.match_detail_px == detail_px
    none, plain = rows[0]["figures"][32], rows[1]["figures"][32]
    assert plain["colour"] < none["colour"]  # the plain map moves the covered pixels' statistics to the painting's
    assert rows[0]["map_offset"] > rows[1]["map_offset"]  # what a match would still do shrinks once it is done
    engine.step()  # the run's own final match then runs as it would have
    assert engine.done


@pytest.mark.slow
def test_command_line_prints_a_row_per_match_and_the_result(cost, vgg, no_clip_weights, monkeypatch, tmp_path, style,
                                                            capsys):
    scene, painting = tiny_bench_inputs(cost, vgg, style, tmp_path, monkeypatch)
    threads = torch.get_num_threads()
    try:
        assert cost.main([str(scene), "--style", str(painting), "--threads", "1", "--detail-px", "0,4"]) == 0
    finally:
        torch.set_num_threads(threads)
    printed = capsys.readouterr().out.strip().splitlines()
    assert any(line.startswith("none ") for line in printed)
    assert any(line.startswith("detail 0 px") for line in printed) and any(line.startswith("detail 4 px")
                                                                           for line in printed)
    assert printed[-1].startswith("RESULT width=32 drop_without_match=") and "drop_with_match=-" not in printed[-1]
