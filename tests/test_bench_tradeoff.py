"""The atlas (``bench/tradeoff.py``): end to end through ``gstyle batch`` on a tiny scene and painting (every column of
its row filled), its fronts and merges (``bench/tradeoff_report.py``), and the tiers' tables of the README and the
guide against the atlas CSV the repository ships (``docs/atlas.csv``)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from bench_cli import load_bench, tiny_bench_inputs

from gstyle_core.engine.build import evaluation_width

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def report():
    return load_bench("tradeoff_report")


def test_the_atlas_runs_through_the_batch_and_fills_every_column(vgg, no_clip_weights, monkeypatch, tmp_path,
                                                                  capsys):
    from gstyle_core.cli import stylize as cli

    tradeoff = load_bench("tradeoff")
    style = np.random.default_rng(0).uniform(size=(16, 16, 3)).astype(np.float32)
    scene, painting = tiny_bench_inputs(cli, vgg, style, tmp_path, monkeypatch)  # every job: TINY settings
    monkeypatch.chdir(tmp_path)  # the scene given relative to here (as --fern out/fern.ply): the plan holds it whole
    monkeypatch.setattr(tradeoff, "SCENES", {"tiny": (Path(scene).relative_to(tmp_path), None)})
    monkeypatch.setattr(tradeoff, "PAINTINGS", {"noise": painting})
    monkeypatch.setattr(tradeoff, "DISPLAY_WIDTH", 64)
    out, work = tmp_path / "atlas.csv", tmp_path / "work"
    argv = ["--tiers", "preview", "--devices", "cpu-fp32", "--scenes", "tiny", "--paintings", "noise",
            "--repeats", "2", "--threads", "1", "--work", str(work), "--out", str(out)]
    threads = torch.get_num_threads()
    try:
        assert tradeoff.main(argv) == 0
    finally:
        torch.set_num_threads(threads)
    captured = capsys.readouterr()
    printed = captured.out.strip().splitlines()
    assert printed[-1] == "RESULT points=1 pareto=1 groups=1", captured.out + captured.err
    for k in (1, 2):  # one batch per repeat, each with its job's outputs and batch.csv (the plan's run per scene)
        folder = work / "preview_cpu-fp32_as_shipped" / f"repeat{k}"
        assert (folder / "batch.csv").is_file() and (folder / "tiny__style__tiny.ply").is_file()
    with out.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 1
    row = rows[0]
    assert [k for k, v in row.items() if v == ""] == []  # every column filled
    assert (row["tier"], row["device"], row["scene"], row["painting"], row["knob"]) == (
        "preview", "cpu-fp32", "tiny", "noise", "as shipped")
    assert int(row["repeats"]) == 2 and int(row["working_width"]) == 32 and int(row["end_width"]) == evaluation_width()
    assert 0 < float(row["seconds_min"]) <= float(row["seconds"]) <= float(row["seconds_max"])
    for key in ("nnfm_drop", "structure", "nnfm_drop_end", "structure_end", "nnfm_drop_1024", "speckle_1024",
                "structure_1024", "coarse_ratio", "colour", "consistency", "consistency_input", "load_before",
                "load_after", "nnfm_drop_spread", "structure_1024_spread"):
        assert math.isfinite(float(row[key])), key
    assert row["nnfm_drop"] == row["nnfm_drop_end"]  # a preview ends at the width it is measured at
    assert "cores" in row["machine"] and row["torch"] == torch.__version__
    try:  # the plot needs the bench extra (matplotlib); without it the atlas says so and writes the CSV all the same
        import matplotlib  # noqa: F401
    except ImportError:
        assert "matplotlib not installed (pip install -e .[bench]): no plot" in printed
    else:
        assert (tmp_path / "atlas_cpu-fp32.png").is_file()
    assert tradeoff.main(["--table", "--out", str(out)]) == 0
    table = capsys.readouterr().out.strip().splitlines()
    assert len(table) == 3 and table[2].startswith("| preview | cpu-fp32 | tiny / noise |")
    assert float(row["nnfm_drop_spread"]) < 0.01 and f"% (Δ {100 * float(row['nnfm_drop_spread']):.1f})" in table[2]


def test_the_groups_are_every_tier_on_every_device_or_the_knobs_on_their_pairs():
    tradeoff = load_bench("tradeoff")
    groups = tradeoff.atlas_groups(tradeoff.parse_args(["--tiers", "preview,final"]), ["cpu-fp32", "cuda"])
    assert [(g[0], g[1], g[2][0]) for g in groups] == [("preview", "cpu-fp32", "as shipped"),
                                                       ("preview", "cuda", "as shipped"),
                                                       ("final", "cpu-fp32", "as shipped"),
                                                       ("final", "cuda", "as shipped")]
    assert groups[0][3:] == (["fountain", "fern"], list(tradeoff.ATLAS_PAINTINGS))  # the extra paintings by name only
    whole = ["--knobs", "refine whole views", "--scenes", "fern", "--paintings", "hat,wave"]
    (alone,) = tradeoff.atlas_groups(tradeoff.parse_args(whole), ["cpu-bf16", "cuda"])
    assert alone == ("balanced", "cpu-bf16", ("refine whole views", ["--refine-mode", "whole"]), ["fountain"],
                     ["starry"])  # the knob's own pair, whatever --scenes says
    (paired,) = tradeoff.atlas_groups(tradeoff.parse_args([*whole, "--knob-pairs"]), ["cpu-bf16"])
    assert paired[3:] == (["fern"], ["hat", "wave"])
    with pytest.raises(tradeoff.GStyleError, match="unknown knob"):
        tradeoff.atlas_groups(tradeoff.parse_args(["--knobs", "louder"]), ["cpu-bf16"])


def test_a_point_that_loses_the_structure_at_1024_px_is_never_on_the_front(report):
    points = [{"seconds": 10.0, "nnfm_drop": 0.30, "structure_1024": 0.8},
              {"seconds": 10.0, "nnfm_drop": 0.45, "structure_1024": 0.3},  # more style, scene lost
              {"seconds": 20.0, "nnfm_drop": 0.35, "structure_1024": 0.6},
              {"seconds": 30.0, "nnfm_drop": 0.32, "structure_1024": 0.7}]  # slower and less than the third
    assert report.pareto(points) == [True, False, True, False]
    # with the drop at 1024 px on every point the front is drawn on it: the slow point with the most there joins
    at_display = [{**p, "nnfm_drop_1024": d} for p, d in zip(points, (0.05, 0.20, 0.06, 0.12), strict=True)]
    assert report.front_figure(at_display) == "nnfm_drop_1024" and report.front_figure(points) == "nnfm_drop"
    assert report.pareto(at_display) == [True, False, True, True]


def test_merge_replaces_the_points_measured_again_and_keeps_the_others(report):
    def point(tier, device, seconds):
        return {"tier": tier, "device": device, "scene": "s", "painting": "p", "knob": "as shipped",
                "seconds": seconds}

    old = [point("preview", "cpu-fp32", 30.0), point("balanced", "cpu-fp32", 90.0)]
    new = [point("preview", "cpu-fp32", 28.0), point("preview", "cpu-bf16", 22.0)]
    assert [(r["tier"], r["device"], r["seconds"]) for r in report.merged(old, new)] == [
        ("balanced", "cpu-fp32", 90.0), ("preview", "cpu-fp32", 28.0), ("preview", "cpu-bf16", 22.0)]


def test_the_tiers_table_reads_its_rows_ranges_and_dashes(report):
    def row(tier, device, scene, painting, seconds, **figures):
        return {"tier": tier, "device": device, "scene": scene, "painting": painting, "knob": "as shipped",
                "seconds": seconds, **figures}

    rows = [row("preview", "cpu-bf16", "fountain", "starry", 21.6, nnfm_drop_1024=0.0904, structure_1024=0.651,
                speckle_1024=0.5249),
            row("preview", "cpu-bf16", "fern", "wave", 30.4), row("preview", "cpu-bf16", "fern", "scream", 99.0),
            row("preview", "cuda", "fountain", "wave", 8.7),
            {**row("final", "cpu-bf16", "fountain", "starry", 70.0), "knob": "epochs 3"}]  # a knob: not shipped
    lines = report.tiers_table(rows)
    assert lines[2] == "| `preview` | 22 s | 9.0 % | 0.65 | 0.52 | 22–30 s | 9 s |"  # scream: not one of the three
    assert lines[3] == lines[4].replace("`final`", "`balanced`") == "| `balanced` | – | – | – | – | – | – |"
    page = f"intro\n{report.TABLE_BEGIN}\nold\n{report.TABLE_END}\noutro\n"
    assert report.with_tiers_table(page, rows).splitlines() == ["intro", report.TABLE_BEGIN, *lines,
                                                                 report.TABLE_END, "outro"]
    assert report.generated_block(report.with_tiers_table(page, rows)) == lines


@pytest.mark.parametrize("page", ["README.md", "docs/tiers.md"])
def test_the_tiers_tables_are_the_atlas_csvs(report, page):
    """The README's and the guide's tables are generated from the shipped CSV: rerun ``bench/tradeoff.py
    --tiers-table`` after the atlas changes."""
    rows = report.read_rows(ROOT / "docs" / "atlas.csv")
    assert report.generated_block((ROOT / page).read_text(encoding="utf-8")) == report.tiers_table(rows)
