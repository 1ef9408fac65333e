"""``gstyle batch --ray`` (issue #50 item 1): the jobs as tasks of a local Ray cluster started by the test (2 CPUs)
write what the local pool writes, a killed batch or a lost worker loses no finished job, a failed job is one line.
The stand-in engine (``batch_worker.py``) runs the jobs, as in ``test_batch.py``; one test runs the real engine at a
tiny size through both and compares the figures and colours. Skipped only when the ``ray`` extra is absent."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_batch import TAILS, batch_args, make_inputs, names, painting, rows_of

from gstyle_core.batch import jobs as batch_jobs
from gstyle_core.batch import ray_tasks as batch_ray
from gstyle_core.cli import run

ray = pytest.importorskip("ray", reason="the 'ray' extra is not installed (pip install -e '.[ray]')")
WORKER_SCRIPT = str(Path(__file__).with_name("batch_worker.py"))
CACHE = os.environ.get("GSTYLE_CACHE", "")  # the suite's cache folder (the VGG weights), read at import


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of 2 CPUs for the module; the batches keep this process's connection (``--ray auto``)."""
    t0 = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
    print(f"Ray started in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    yield
    ray.shutdown()


@pytest.fixture
def inputs(tmp_path, monkeypatch) -> dict:
    """``test_batch``'s two scenes and two paintings."""
    return make_inputs(tmp_path, monkeypatch)


@pytest.fixture
def stand_in(monkeypatch):
    """The pool's and the Ray tasks' jobs run the stand-in engine."""
    monkeypatch.setattr(batch_jobs, "WORKER", [sys.executable, WORKER_SCRIPT])


def outputs_of(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.is_file() and p.suffix in (".ply", ".png")
            and p.name != "contact_sheet.png"}


@pytest.mark.slow
def test_a_batch_on_ray_writes_what_the_local_pool_writes(cluster, stand_in, inputs, capsys):
    local, remote = inputs["out"].with_name("local"), inputs["out"]
    assert run(batch_args(dict(inputs, out=local), "--jobs", "2", "--threads", "1", "--strength", "2")) == 0
    assert run(batch_args(inputs, "--ray", "auto", "--strength", "2")) == 0
    err = capsys.readouterr().err
    assert "4 to run on the Ray cluster (2 CPUs, 0 GPUs), 1 threads each" in err
    assert "4 of 4 done (0 already), 0 running, 0 failed" in err
    ours = outputs_of(remote)
    assert sorted(ours) == sorted(name + tail for name in names() for tail in TAILS if tail != ".json")
    assert ours == outputs_of(local)  # the scenes and pictures bit for bit (the after picture: the painting's colour)
    for name in names():
        ray_json, pool_json = (json.loads((d / f"{name}.json").read_text()) for d in (remote, local))
        assert ray_json["quality"] == pool_json["quality"] and ray_json["settings"] == pool_json["settings"]
        scene, style = name.split("__")
        assert Path(ray_json["source_scene"]) == Path(inputs["scenes"][int(scene[-1]) - 1]).resolve()
        assert ray_json["style"] == ray_json["styles"][0]["path"] == str(Path(inputs["out"].parent / f"{style}.png"))
        assert "wrote " in (remote / "logs" / f"{name}.log").read_text()
    strip = lambda rows: [{k: v for k, v in r.items() if k not in ("seconds", "out")} for r in rows]  # noqa: E731
    assert strip(rows_of(remote)) == strip(rows_of(local))
    assert not list(remote.glob(".*.part"))

    assert run(batch_args(inputs, "--ray", "auto")) == 0  # a rerun: nothing to run, no task
    assert "4 jobs, 4 done already; nothing to run" in capsys.readouterr().err


def test_a_killed_batch_keeps_its_finished_jobs_and_a_lost_worker_runs_again(cluster, inputs, monkeypatch, capsys):
    out, marker = inputs["out"], inputs["out"].with_name("killed-once")
    monkeypatch.setattr(batch_jobs, "WORKER", [sys.executable, WORKER_SCRIPT, "--kill-parent-once", str(marker)])
    write_back, written = batch_ray.write_back, []

    def ctrl_c_after_two(job, result):
        write_back(job, result)
        written.append(job.out.name)
        if len(written) == 2:
            raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(batch_ray, "write_back", ctrl_c_after_two)
        assert run(batch_args(inputs, "--ray", "auto")) == 130
    assert marker.exists()  # one job's Ray worker was killed; Ray ran its task again
    assert sorted(p.name for p in out.glob("*.ply")) == sorted(written)
    assert all((out / (Path(name).stem + tail)).is_file() for name in written for tail in TAILS)
    capsys.readouterr()
    assert run(batch_args(inputs, "--ray", "auto")) == 0
    assert "4 jobs, 2 done already; 2 to run on the Ray cluster" in capsys.readouterr().err
    assert sorted(r["status"] for r in rows_of(out)) == ["done", "done", "done already", "done already"]


@pytest.mark.slow
def test_a_failed_job_on_ray_is_one_line_and_a_rerun_does_the_rest(cluster, stand_in, inputs, capsys):
    assert run(batch_args(inputs, "--ray", "auto", "--max-gaussians", "0")) == 1  # the options reach the jobs
    assert capsys.readouterr().err.count("failed: gstyle stylize: error: --max-gaussians must be at least 1") == 4
    blue = Path(inputs["paintings"][1])
    blue.write_bytes(b"not a painting")
    assert run(batch_args(inputs, "--ray", "auto")) == 1
    err = capsys.readouterr().err
    failed = [line for line in err.splitlines() if " failed: " in line]
    assert len(failed) == 2 and all("after blue.png failed: gstyle stylize: error: " in line for line in failed), err
    assert "Traceback" not in err
    assert [r["status"] for r in rows_of(inputs["out"])] == ["done", "failed", "done", "failed"]
    painting((20, 20, 220)).save(blue, format="PNG")
    assert run(batch_args(inputs, "--ray", "auto")) == 0
    assert [r["status"] for r in rows_of(inputs["out"])] == ["done already", "done", "done already", "done"]


def test_without_ray_installed_the_batch_says_which_extra_to_install(inputs, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails as when it is not installed
    assert run(batch_args(inputs, "--ray", "auto")) == 2
    assert capsys.readouterr().err.splitlines() == [f"gstyle batch: error: {batch_ray.NEEDS_RAY}"]


@pytest.mark.slow
def test_the_real_engine_on_ray_gives_the_local_pool_s_figures_and_colours(cluster, inputs, monkeypatch):
    from gstyle_core.io import load_scene

    if CACHE:  # the suite's cache folder (VGG weights) for the local pool too
        monkeypatch.setenv("GSTYLE_CACHE", CACHE)
    else:
        monkeypatch.delenv("GSTYLE_CACHE")
    tiny = ["--working-width", "32", "--display-width", "0", "--refine-widths", "0", "--precision", "fp32",
            "--threads", "1"]
    one = dict(inputs, scenes=inputs["scenes"][:1])
    local, remote = inputs["out"].with_name("local"), inputs["out"]
    assert run(batch_args(dict(one, out=local), "--jobs", "2", *tiny)) == 0
    assert run(batch_args(one, "--ray", "auto", *tiny)) == 0
    for name in ("scene1__red", "scene1__blue"):
        ray_json, pool_json = (json.loads((d / f"{name}.json").read_text()) for d in (remote, local))
        assert ray_json["quality"] == pool_json["quality"] and ray_json["quality"]["nnfm_drop"] > 0
        ours, theirs = (load_scene(str(d / f"{name}.ply"))[0] for d in (remote, local))
        assert np.array_equal(ours.sh_dc, theirs.sh_dc) and ours.count == theirs.count
