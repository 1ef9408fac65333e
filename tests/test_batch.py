"""``gstyle batch`` (issue #50 item 1, local pool): every scene after every painting as ``gstyle stylize`` jobs with
their own outputs, skipped when finished and resumed when interrupted; a failed job is one line and the others go
on; batch.csv and contact_sheet.png at the end. The jobs run the stand-in engine (``batch_worker.py``): in the test's
process with ``--jobs 1``, as subprocesses of the worker script with ``--jobs 2``."""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from batch_worker import use_tiny_engine
from PIL import Image
from synthetic import blob_scene

from gstyle_core.batch import jobs as batch_jobs
from gstyle_core.batch import pool as batch
from gstyle_core.batch.report import CELL_WIDTH, CSV_COLUMNS, FAILED_GREY, TEXT_HEIGHT
from gstyle_core.cli import run
from gstyle_core.cli.stylize import add_stylize_arguments
from gstyle_core.engine.checkpoint import stylize_checkpoint_path
from gstyle_core.io import save_scene

TAILS = (".ply", ".json", "_before.png", "_after.png")
PICTURE = -(-CELL_WIDTH // 3)  # the stand-in's after pictures are 3:1: 256 px wide, 86 high (rounded up)


@pytest.fixture
def inputs(tmp_path, monkeypatch) -> dict:
    """Two tiny scenes, two paintings (reddish, bluish), a private cache folder."""
    return make_inputs(tmp_path, monkeypatch)


def make_inputs(tmp_path: Path, monkeypatch) -> dict:
    """``inputs``' files in ``tmp_path``."""
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    scenes = []
    for k in (1, 2):
        scenes.append(tmp_path / f"scene{k}.ply")
        save_scene(blob_scene(40, seed=k), scenes[-1])
    paintings = []
    for name, colour in (("red", (220, 20, 20)), ("blue", (20, 20, 220))):
        paintings.append(tmp_path / f"{name}.png")
        painting(colour).save(paintings[-1])
    return {"scenes": [str(p) for p in scenes], "paintings": [str(p) for p in paintings], "out": tmp_path / "batch"}


def painting(colour: tuple[int, int, int]) -> Image.Image:
    """A 32×24 painting of ``colour`` with some noise (a single colour is warned about)."""
    noise = np.random.default_rng(0).integers(-20, 20, (24, 32, 3))
    return Image.fromarray(np.clip(np.array(colour) + noise, 0, 255).astype(np.uint8))


def batch_args(inputs: dict, *extra: str) -> list[str]:
    return ["batch", "--scenes", *inputs["scenes"], "--styles", *inputs["paintings"], "--out", str(inputs["out"]),
            "--checkpoint-every", "0", *extra]


def names() -> list[str]:
    return [f"scene{s}__{p}" for s in (1, 2) for p in ("red", "blue")]


def rows_of(out: Path) -> list[dict]:
    with open(out / "batch.csv", newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        assert tuple(reader.fieldnames) == CSV_COLUMNS
        return list(reader)


def test_every_scene_after_every_painting_then_a_rerun_skips_them_all(inputs, monkeypatch, capsys):
    built = []
    use_tiny_engine(monkeypatch.setattr, built)
    out = inputs["out"]
    assert run(batch_args(inputs, "--jobs", "1", "--strength", "2")) == 0
    for name in names():
        assert all((out / (name + tail)).is_file() for tail in TAILS), name
    assert [(Path(r.scene).stem, Path(r.style[0]).stem) for r in built] == [
        ("scene1", "red"), ("scene1", "blue"), ("scene2", "red"), ("scene2", "blue")]
    assert {r.overrides["strength"] for r in built} == {2.0}  # the stylize options reach every job
    rows = rows_of(out)
    assert [(Path(r["scene"]).stem, Path(r["painting"]).stem, r["status"]) for r in rows] == [
        (n.split("__")[0], n.split("__")[1], "done") for n in names()]
    assert {(r["preset"], r["nnfm_drop"], r["structure"], r["speckle_ratio"], r["speckle_width"]) for r in rows} == {
        ("preview", "0.25", "0.8", "1.25", "1024")}  # 1 - 1.5 / 2.0, read from each OUT.json
    assert all(0 <= float(r["seconds"]) < 5 for r in rows)  # each job's wall time, a number
    with Image.open(out / "contact_sheet.png") as sheet:
        assert sheet.size == (2 * CELL_WIDTH, 2 * (PICTURE + TEXT_HEIGHT))
        red, blue = sheet.getpixel((CELL_WIDTH // 2, PICTURE // 2)), sheet.getpixel((3 * CELL_WIDTH // 2, PICTURE // 2))
    assert red[0] > 150 > red[2] and blue[2] > 150 > blue[0]  # scenes as rows, paintings as columns
    assert "4 of 4 done (0 already), 0 running, 0 failed" in capsys.readouterr().err

    t0 = time.perf_counter()
    assert run(batch_args(inputs, "--jobs", "1")) == 0
    assert time.perf_counter() - t0 < 5 and len(built) == 4  # nothing was built again
    err = capsys.readouterr().err
    assert "4 jobs, 4 done already; nothing to run" in err
    assert [r["status"] for r in rows_of(out)] == ["done already"] * 4


def test_a_failed_job_is_one_line_the_others_finish_and_a_rerun_does_the_rest(inputs, monkeypatch, capsys):
    monkeypatch.setattr(batch_jobs, "WORKER", [sys.executable, str(Path(__file__).with_name("batch_worker.py"))])
    blue = Path(inputs["paintings"][1])
    blue.write_bytes(b"not a painting")
    out = inputs["out"]
    assert run(batch_args(inputs, "--jobs", "2", "--threads", "1")) == 1
    err = capsys.readouterr().err
    failed = [line for line in err.splitlines() if " failed: " in line]
    assert len(failed) == 2 and all(line.startswith("batch: scene") and "after blue.png failed: gstyle stylize: "
                                    "error: " in line for line in failed), err
    assert "Traceback" not in err and "2 of 4 done (0 already), 0 running, 2 failed" in err
    assert sorted(p.name for p in out.glob("*.ply")) == ["scene1__red.ply", "scene2__red.ply"]
    assert [r["status"] for r in rows_of(out)] == ["done", "failed", "done", "failed"]
    with Image.open(out / "contact_sheet.png") as sheet:
        assert sheet.getpixel((3 * CELL_WIDTH // 2, 4)) == FAILED_GREY  # the failed job's cell
        assert sheet.getpixel((CELL_WIDTH // 2, PICTURE // 2))[0] > 150

    painting((20, 20, 220)).save(blue, format="PNG")  # the painting fixed
    assert run(batch_args(inputs, "--jobs", "2", "--threads", "1")) == 0
    assert "4 jobs, 2 done already; 2 to run 2 at a time, 1 threads each" in capsys.readouterr().err
    assert [r["status"] for r in rows_of(out)] == ["done already", "done", "done already", "done"]


def test_a_rerun_after_ctrl_c_resumes_the_stopped_job_and_keeps_the_finished_one(inputs, monkeypatch, capsys):
    import os
    import signal

    from test_outputs_stylize import TinyEngine

    built, step = [], TinyEngine.step

    def ctrl_c_in_the_second_job(engine):
        if len(built) == 2 and engine.global_step == 4:
            os.kill(os.getpid(), signal.SIGINT)  # as Ctrl+C: the step ends, the checkpoint is written
        return step(engine)

    use_tiny_engine(monkeypatch.setattr, built)
    out = inputs["out"]
    with monkeypatch.context() as patch:
        patch.setattr(TinyEngine, "step", ctrl_c_in_the_second_job)
        assert run(batch_args(inputs, "--jobs", "1")) == 130
    assert sorted(p.name for p in out.glob("*.ply")) == ["scene1__red.ply"]
    assert stylize_checkpoint_path(out / "scene1__blue.ply").exists()
    capsys.readouterr()
    assert run(batch_args(inputs, "--jobs", "1")) == 0
    assert "4 jobs, 1 done already; 3 to run" in capsys.readouterr().err
    assert "resumed from" in (out / "logs" / "scene1__blue.log").read_text() and len(built) == 2 + 3
    assert [r["status"] for r in rows_of(out)] == ["done already", "done", "done", "done"]
    assert not stylize_checkpoint_path(out / "scene1__blue.ply").exists()


def test_an_interrupted_job_resumes_and_force_runs_all_again(inputs):
    from gstyle_core.cli import build_parser

    out = inputs["out"]
    stylize_checkpoint_path(out / "scene1__blue.ply").parent.mkdir(parents=True, exist_ok=True)
    stylize_checkpoint_path(out / "scene1__blue.ply").write_bytes(b"")
    out.mkdir(exist_ok=True)
    (out / "scene2__red.ply").write_bytes(b"")
    argv = batch_args(inputs, "--lambda-nnfm", "3", "--region=-1,-1,-1,1,1,1")

    def plan(*extra: str) -> dict:
        args = build_parser().parse_args(argv + list(extra))
        args.argv = argv + list(extra)
        return {job.out.stem: job for job in batch.plan_jobs(args, out, add_stylize_arguments)}

    jobs = plan()
    assert jobs["scene1__blue"].argv[-1] == "--resume" and "--resume" not in jobs["scene1__red"].argv
    assert jobs["scene2__red"].status == "done already" and jobs["scene1__red"].status == "pending"
    assert jobs["scene1__red"].argv == ["stylize", inputs["scenes"][0], "--style", inputs["paintings"][0],
                                        "--checkpoint-every", "0", "--lambda-nnfm", "3", "--region=-1,-1,-1,1,1,1",
                                        "--out", str(out / "scene1__red.ply")]
    forced = plan("--force")
    assert {job.status for job in forced.values()} == {"pending"} and "--resume" not in forced["scene1__blue"].argv


@pytest.mark.parametrize("cores, gpus, jobs, threads, pending, expected", [
    (4, 0, None, None, 10, (4, 1, 0)),  # one thread a job by default
    (4, 0, None, 2, 10, (2, 2, 0)),
    (4, 0, None, 1, 10, (4, 1, 0)),
    (4, 0, 1, None, 10, (1, 4, 0)),
    (16, 0, None, None, 3, (3, 5, 0)),  # no more slots than jobs
    (16, 2, None, None, 10, (2, 8, 2)),  # one job per GPU
])
def test_pool_size(monkeypatch, cores, gpus, jobs, threads, pending, expected):
    import argparse

    from gstyle_core import machine

    monkeypatch.setattr(machine, "usable_cores", lambda: cores)
    monkeypatch.setattr(batch, "cuda_gpus", lambda args: gpus)
    assert batch.pool_size(argparse.Namespace(jobs=jobs, threads=threads), pending) == expected


def test_bad_batches_are_one_line(inputs, capsys):
    assert run(batch_args(inputs, "--jobs", "0")) == 2
    assert run(batch_args(inputs, "--style", inputs["paintings"][0])) == 2
    same = ["batch", "--scenes", inputs["scenes"][0], inputs["scenes"][0], "--styles", inputs["paintings"][0],
            "--out", str(inputs["out"])]
    assert run(same) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == ["gstyle batch: error: --jobs and --threads must be at least 1",
                   "gstyle batch: error: give the scenes with --scenes and the paintings with --styles",
                   f"gstyle batch: error: two jobs would both write {inputs['out'] / 'scene1__red'}.ply: give scenes "
                   "and paintings different names"]
    assert not np.any([p.suffix == ".ply" for p in inputs["out"].glob("*")])
