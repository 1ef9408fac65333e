"""Captures of artists' sizes, scaled down for CI (issue #58): memory per Gaussian within the model the run's cap is
derived from, and the paths that refuse or reduce, each one line and never fewer Gaussians out than in.

The full sizes (1.2 M and 6 M) and their times are ``bench/engine_scale.py``'s (docs/notes/captures.md)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gstyle_core.assets import DEMO_SCENE
from gstyle_core.engine.resources import bytes_per_gaussian
from gstyle_core.io import load_scene

ROOT = Path(__file__).resolve().parents[1]


def _probe(n: int) -> dict:
    done = subprocess.run([sys.executable, str(ROOT / "tests" / "scale_probe.py"), str(n)], capture_output=True,
                          text=True, check=False, cwd=ROOT)
    lines = [line for line in done.stdout.splitlines() if line.startswith("PROBE ")]
    assert done.returncode == 0 and lines, done.stderr[-3000:]
    return json.loads(lines[-1][len("PROBE "):])


def _gstyle(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gstyle_core.cli", *args], capture_output=True, text=True,
                          check=False, cwd=ROOT)


@pytest.mark.slow
def test_memory_per_gaussian_stays_within_the_caps_model_at_200k():
    """The slope of peak memory over the Gaussians held, between 50k and 200k made from the demo, is below the model
    ``resources.bytes_per_gaussian`` that the default cap divides the available memory by: the cap never promises
    more Gaussians than fit."""
    small, large = _probe(50_000), _probe(200_000)
    assert large["out"] >= 200_000 and small["out"] >= 50_000  # never fewer out than in
    slope = (large["peak"] - small["peak"]) / (large["most"] - small["most"])
    assert 0 < slope <= bytes_per_gaussian(256), f"{slope:.0f} bytes a Gaussian at 256 px"


def test_a_header_claiming_a_billion_gaussians_is_one_line(tmp_path):
    fields = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0",
              "rot_1", "rot_2", "rot_3"]
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\n"
              + "".join(f"property float {f}\n" for f in fields) + "end_header\n")
    path = tmp_path / "hostile.ply"
    path.write_bytes(header.encode() + np.zeros(100 * len(fields), np.float32).tobytes())
    out = tmp_path / "out.ply"
    done = _gstyle("stylize", str(path), "--out", str(out))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "truncated" in done.stderr
    assert not list(tmp_path.glob("out*"))  # no output, not even a partial one


@pytest.mark.parametrize("cap", ["0", "-5"])
def test_a_cap_below_one_is_refused_before_anything_loads(tmp_path, cap):
    done = _gstyle("stylize", "--max-gaussians", cap, "--out", str(tmp_path / "o.ply"))
    assert done.returncode == 2 and "Traceback" not in done.stderr and "--max-gaussians" in done.stderr


@pytest.mark.slow
def test_a_capture_over_the_cap_is_stylized_in_part_and_written_whole(tmp_path):
    """``--max-gaussians`` below the demo's count: the plan is printed before the first step and kept in OUT.json;
    the result holds every input Gaussian."""
    n_in = load_scene(DEMO_SCENE)[0].count
    out = tmp_path / "out.ply"
    done = _gstyle("stylize", "--max-gaussians", str(n_in // 2), "--working-width", "64", "--display-width", "0",
                   "--lod", "off", "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.replace("\r", "\n").splitlines()
    plan = next(i for i, line in enumerate(lines) if line.startswith("capacity: "))
    assert f"the other {n_in - n_in // 2:,} keep their shape" in lines[plan]
    assert not any("step/s" in line or "s/step" in line for line in lines[:plan])  # said before the run
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["decisions"]["capacity"] == lines[plan][len("capacity: "):]
    assert record["gaussians_after"] >= n_in == record["gaussians_before"]
    assert load_scene(out)[0].count == record["gaussians_after"]


@pytest.mark.slow
def test_a_200k_capture_on_the_level_of_detail_writes_every_gaussian_with_figures_in_bounds(tmp_path):
    """200k Gaussians densified from the demo, stylized on a cut (``--lod on``): the cut is said before the first
    step and kept in OUT.json, the run holds fewer Gaussians than came in, every input Gaussian is written, and the
    figures say the painting arrived and the scene's structure stayed."""
    import sys as _sys

    _sys.path.insert(0, str(ROOT / "bench"))
    from densify import densify

    from gstyle_core.io import save_scene

    demo, _ = load_scene(DEMO_SCENE)
    scene = densify(demo, 200_000)
    path = tmp_path / "capture.ply"
    save_scene(scene.subset(np.random.default_rng(0).permutation(scene.count)), path)  # a file's order says nothing
    out = tmp_path / "out.ply"
    done = _gstyle("stylize", str(path), "--lod", "on", "--working-width", "128", "--display-width", "0",
                   "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.replace("\r", "\n").splitlines()
    said = next(i for i, line in enumerate(lines) if line.startswith("level of detail: "))
    assert not any("step/s" in line or "s/step" in line for line in lines[:said])  # said before the run
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["decisions"]["lod"] == lines[said][len("level of detail: "):]
    parents = int(record["decisions"]["lod"].split(" parents")[0].split(" as ")[1].replace(",", ""))
    assert parents < 200_000 // 2
    assert record["gaussians_after"] >= 200_000 == record["gaussians_before"]
    back, _ = load_scene(out)
    assert back.count == record["gaussians_after"]
    q = record["quality"]
    assert 0.1 < q["nnfm_drop"] < 1 and 0.3 < q["structure"] <= 1, q
