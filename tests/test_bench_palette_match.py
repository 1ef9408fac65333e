"""``bench/studies/palette_match.py`` on a tiny scene: one run, its pictures and figures at each palette-match
strength."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from bench_cli import load_bench, tiny_bench_inputs
from PIL import Image


@pytest.mark.slow
def test_one_run_gives_a_picture_and_a_row_per_strength(vgg, no_clip_weights, monkeypatch, tmp_path, capsys):
    bench = load_bench("studies/palette_match")
    style = (np.random.default_rng(1).uniform(size=(16, 16, 3)) * np.array([0.9, 0.3, 0.6])).astype(np.float32)
    scene, painting = tiny_bench_inputs(bench, vgg, style, tmp_path, monkeypatch)
    threads = torch.get_num_threads()
    try:
        assert bench.main([str(scene), "--style", str(painting), "--threads", "1", "--display-width", "64",
                           "--out-dir", str(tmp_path / "out")]) == 0
    finally:
        torch.set_num_threads(threads)
    printed = capsys.readouterr().out.strip().splitlines()
    pictures = [np.asarray(Image.open(tmp_path / "out" / f"palette_match_{t}.png")) for t in ("0", "0.5", "1")]
    assert all(p.shape[1] == 64 for p in pictures) and not np.array_equal(pictures[0], pictures[2])
    rows = {line.split()[0]: line.split() for line in printed if line.split()[0] in ("0", "0.5", "1")}
    assert list(rows) == ["0", "0.5", "1"]
    colour = {t: float(row[4]) for t, row in rows.items()}  # the distance to the painting's palette
    assert colour["1"] < colour["0.5"] < colour["0"], printed  # the full match brings the palette, the blend
    # lies on the way
    assert printed[-1].startswith("RESULT t0:drop=") and " t0.5:drop=" in printed[-1] and " t1:drop=" in printed[-1]
