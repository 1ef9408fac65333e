"""Smoke test of ``bench/tradeoff.py --quick``: two tiny points on a tiny scene, CSV and RESULT line (seconds)."""

from __future__ import annotations

import csv
import math
import sys

import numpy as np
import pytest
import torch
from bench_cli import load_bench
from synthetic import blob_scene

from gstyle_core.io import save_scene

TINY = {"epochs": 1.0, "min_steps": 2, "max_views": 2, "refit_iterations": 2, "preprocess_rounds": 1}


@pytest.fixture
def tradeoff(tmp_path, monkeypatch, vgg, no_clip_weights):
    """The bench module on a 150-Gaussian scene, a 16 px style and a random VGG (no weights needed)."""
    from PIL import Image

    from gstyle_core.style import vgg as vgg_module

    module = load_bench("tradeoff")
    scene, style = tmp_path / "tiny.ply", tmp_path / "style.png"
    save_scene(blob_scene(150, seed=2), scene)
    Image.fromarray((np.random.default_rng(0).uniform(size=(16, 16, 3)) * 255).astype(np.uint8)).save(style)
    monkeypatch.setattr(module, "SCENES", {"demo": (str(scene), None)})
    monkeypatch.setattr(module, "STYLES", {"starry": style})
    monkeypatch.setattr(module, "QUICK_SWEEP", [("w32", "preview", {**TINY, "working_width": 32}),
                                                ("w48", "preview", {**TINY, "working_width": 48})])
    monkeypatch.setattr(module, "EVAL_WIDTH", 48)
    monkeypatch.setattr(vgg_module, "load_vgg", lambda *a, **k: vgg)
    threads = torch.get_num_threads()
    yield module
    torch.set_num_threads(threads)  # main() sets the process' torch threads


def test_quick_sweep_writes_both_points_and_the_result_line(tradeoff, tmp_path, monkeypatch, capsys):
    out = tmp_path / "tradeoff"
    monkeypatch.setattr(sys, "argv", ["tradeoff.py", "--quick", "--threads", "1", "--out", str(out)])
    tradeoff.main()
    printed = capsys.readouterr().out
    with out.with_suffix(".csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["label"] for r in rows] == ["w32", "w48"]
    assert {r["group"] for r in rows} == {"demo / starry"}
    assert [int(r["working_width"]) for r in rows] == [32, 48]
    for r in rows:
        assert float(r["seconds"]) > 0 and int(r["steps"]) > 0
        assert math.isfinite(float(r["nnfm_drop"])) and math.isfinite(float(r["consistency"]))
        assert 0.0 <= float(r["coarse_added"]) <= 1.0 and float(r["coarse_ratio"]) >= 0.0
    assert any(r["pareto"] == "True" for r in rows)
    assert printed.strip().splitlines()[-1].startswith("RESULT points=2 pareto=")
    monkeypatch.setattr(sys, "argv", ["tradeoff.py", "--table", "--out", str(out)])
    tradeoff.main()
    table = capsys.readouterr().out.strip().splitlines()
    assert [line.split(" | ")[1] for line in table] == ["w32", "w48"]
    assert all(line.startswith("| demo / starry |") and line.count("|") == 12 for line in table)  # 11 columns


def test_a_point_that_loses_the_structure_is_never_on_the_front(tradeoff):
    points = [{"seconds": 10.0, "nnfm_drop": 0.30, "structure": 0.8},
              {"seconds": 10.0, "nnfm_drop": 0.45, "structure": 0.3},  # more style, scene lost
              {"seconds": 20.0, "nnfm_drop": 0.35, "structure": 0.6},
              {"seconds": 30.0, "nnfm_drop": 0.32}]  # measured before the structure figure: dominated on time
    assert tradeoff.pareto(points) == [True, False, True, False]
