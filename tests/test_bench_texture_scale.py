"""``bench/studies/texture_scale.py`` on a synthetic stylize output: the table's figure, mask and recolour residual."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from bench_cli import load_bench
from PIL import Image

from gstyle_core.style.texture_scale import band_shares


@pytest.fixture(scope="module")
def bench():
    return load_bench("studies/texture_scale")


def _png(path: Path, image: np.ndarray) -> None:
    Image.fromarray((np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)).save(path)


def test_out_row_measures_inside_the_scene(bench, tmp_path):
    h, w = 64, 96
    x = np.arange(w)
    before = np.zeros((h, w, 3))
    before[8:56, 16:80] = 0.4  # a grey square on a black background
    stripes = 0.15 * np.sin(2 * np.pi * x / 24)[None, :, None] * np.ones((h, w, 3))
    after = before.copy()
    after[8:56, 16:80] += stripes[8:56, 16:80]
    after[8:56, 16:80] = 0.5 + 1.2 * (after[8:56, 16:80] - 0.4)  # and a colour change over the whole scene
    painting = tmp_path / "painting.png"
    _png(painting, np.random.default_rng(0).random((40, 60, 3)))
    _png(tmp_path / "run_S0.5_before.png", before)
    _png(tmp_path / "run_S0.5_after.png", after)
    summary = {"style": str(painting), "styles": [{"path": str(painting), "weight": 1.0}],
               "settings": {"working_width": 96, "style_scale": 0.5}, "quality": {"width": 96, "nnfm_drop": 0.3}}
    (tmp_path / "run_S0.5.json").write_text(json.dumps(summary))  # the CLI's name for OUT = run_S0.5.ply
    row = bench.out_row(tmp_path / "run_S0.5.ply")
    assert bench.out_row(tmp_path / "run_S0.5.json")["figure"].added == row["figure"].added
    (tmp_path / "run_S0.5.json").rename(tmp_path / "run_S0.json")  # the name before issue #25: still found
    assert bench.out_row(tmp_path / "run_S0.5.ply")["nnfm_drop"] == 0.3
    b, a = (bench.read_png(tmp_path / f"run_S0.5_{k}.png") for k in ("before", "after"))
    mask = bench.scene_mask(b, a)
    assert mask.sum() == 48 * 64
    np.testing.assert_allclose(row["figure"].added, band_shares(a - b, mask))
    assert row["figure"].painting_side == 48  # 0.5 × max(64, 96) px
    # the residual takes the affine recolouring out: what is left is the stripes (coarse), not the square's edge
    assert row["residual"][2] > row["figure"].added[2]
    assert row["nnfm_drop"] == 0.3


def test_main_prints_paintings(bench, tmp_path, capsys):
    painting = tmp_path / "p.png"
    _png(painting, np.random.default_rng(1).random((50, 80, 3)))
    assert bench.main(["--painting", str(painting), "--side", "40", "160"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and "40 px" in lines[0] and "160 px" in lines[1]
