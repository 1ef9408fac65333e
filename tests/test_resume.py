"""``gstyle stylize`` checkpoints: killed with SIGKILL mid-stylization, resumed, same result as an uninterrupted run;
corrupt, missing and mismatched checkpoints are refused with one line."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from gstyle_core.cli import run
from gstyle_core.engine.checkpoint import (
    CheckpointError,
    engine_fingerprint,
    read_checkpoint,
    save_checkpoint,
    stylize_checkpoint_path,
)
from gstyle_core.errors import WeightsUnavailableError
from gstyle_core.io import load_scene, save_scene
from gstyle_core.paths import cache_dir
from tests.synthetic import blob_scene

ROOT = Path(__file__).resolve().parents[1]
# ~15 s of stylization on one CPU thread: 400 Gaussians, generated cameras, a 48 px working width.
RUN_ARGS = ["--working-width", "48", "--threads", "1", "--checkpoint-every", "0.5", "--max-gaussians", "420"]
# The Stylizer is deterministic for a seed and a checkpoint restores every piece of its state that later steps read
# (parameters, c_s and its Adam moments, accumulated gradients, RNG, counters), and both runs use one torch thread
# (the same reduction order), so the two runs do the same arithmetic: only float noise is tolerated.
REL_TOL = 1e-6
SESSION_CACHE = cache_dir()  # where the test session keeps converted VGG weights (before tests move GSTYLE_CACHE)


@pytest.fixture
def inputs(tmp_path, monkeypatch):
    """A tiny scene and style image, and a private cache folder (GSTYLE_CACHE) for the checkpoints."""
    cache = tmp_path / "cache"
    cache.mkdir()
    monkeypatch.setenv("GSTYLE_CACHE", str(cache))
    scene = tmp_path / "scene.ply"
    save_scene(blob_scene(400, seed=1), scene)
    style = tmp_path / "style.png"
    rng = np.random.default_rng(0)
    Image.fromarray((rng.uniform(0, 1, (64, 64, 3)) * 255).astype(np.uint8)).save(style)
    return scene, style, cache


def _stylize_args(scene, style, out, *extra):
    return ["stylize", str(scene), "--style", str(style), "--out", str(out), *extra]


def test_resume_refuses_corrupt_missing_and_mismatched_checkpoints(inputs, tmp_path, capsys):
    scene, style, _cache = inputs
    out = tmp_path / "out" / "o.ply"
    assert run(_stylize_args(scene, style, out, "--working-width", "48", "--resume")) == 2
    err = capsys.readouterr().err.strip()
    assert "no checkpoint to resume" in err and "\n" not in err

    # a checkpoint made for the same inputs (the CLI's own engine builder), then each input changed in turn
    from gstyle_core.engine.build import BuildRequest, build_stylizer

    engine = build_stylizer(BuildRequest(scene=str(scene), style=str(style), overrides={"working_width": 48})).engine
    for _ in range(3):
        engine.step()
    path = stylize_checkpoint_path(out)
    save_checkpoint(path, engine.state_dict(), {"kind": "stylize", "fingerprint": engine_fingerprint(engine)})
    other_scene = tmp_path / "other.ply"
    save_scene(blob_scene(400, seed=2), other_scene)
    other_style = tmp_path / "style2.png"
    Image.fromarray(np.random.default_rng(5).integers(0, 255, (8, 8, 3), dtype=np.uint8)).save(other_style)
    for args, what in (
        (_stylize_args(other_scene, style, out, "--working-width", "48"), "scene"),
        (_stylize_args(scene, style, out, "--working-width", "48", "--lambda-nnfm", "5"), "settings"),
        (_stylize_args(scene, other_style, out, "--working-width", "48"), "style image"),
    ):
        assert run([*args, "--resume"]) == 2
        err = capsys.readouterr().err.strip()
        assert f"made for a different {what}" in err and "\n" not in err and "Traceback" not in err, err
    assert not out.exists()

    # truncated: one line, no torch traceback
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    assert run(_stylize_args(scene, style, out, "--working-width", "48", "--resume")) == 2
    err = capsys.readouterr().err.strip()
    assert "unreadable" in err and "\n" not in err and "Traceback" not in err
    with pytest.raises(CheckpointError):
        read_checkpoint(path)
    path.write_bytes(b"not a checkpoint at all")
    assert run(_stylize_args(scene, style, out, "--working-width", "48", "--resume")) == 2
    assert "unreadable" in capsys.readouterr().err


def _vgg_into(cache: Path) -> None:
    """Make the VGG weights the session uses (GSTYLE_CACHE of the test run) visible from the private cache."""
    from gstyle_core.style import vgg as vgg_mod

    try:
        _state, _conv, source = vgg_mod.resolve_vgg_weights(cache_dir=SESSION_CACHE)
    except WeightsUnavailableError as exc:
        pytest.skip(f"no VGG-16 weights for a real stylization: {exc}")
    if Path(source).suffix in (".pt", ".pth") and Path(source).name == vgg_mod.CACHE_FILE:
        shutil.copy(source, cache / vgg_mod.CACHE_FILE)
    elif not (cache / vgg_mod.CACHE_FILE).is_file() and Path(source) != vgg_mod.torch_hub_checkpoint():
        vgg_mod.resolve_vgg_weights(cache_dir=cache)  # converts into the private cache


def _gstyle(*args) -> list[str]:
    return [sys.executable, "-m", "gstyle_core.cli", *args]


@pytest.mark.slow
def test_sigkill_mid_stylization_then_resume_matches_an_uninterrupted_run(inputs, tmp_path):
    scene, style, cache = inputs
    _vgg_into(cache)
    env = {**os.environ, "GSTYLE_CACHE": str(cache), "PYTHONPATH": str(ROOT)}
    ref_out, out = tmp_path / "ref" / "o.ply", tmp_path / "run" / "o.ply"
    out.parent.mkdir()
    reference = subprocess.Popen(_gstyle(*_stylize_args(scene, style, ref_out, *RUN_ARGS)), env=env, cwd=ROOT,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    victim = subprocess.Popen(_gstyle(*_stylize_args(scene, style, out, *RUN_ARGS)), env=env, cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ckpt = stylize_checkpoint_path(out)
    deadline = time.monotonic() + 300  # generous: the CPU may be shared; a quiet machine needs ~10 s
    saved = None
    try:
        while time.monotonic() < deadline and victim.poll() is None:
            if ckpt.is_file():
                state, _meta = read_checkpoint(ckpt)
                if state["phase"] == "stylize" and state["phases"]["stylize"]["step_index"] >= 5:
                    saved = state
                    break
            time.sleep(0.2)
    finally:
        victim.send_signal(signal.SIGKILL)
        victim.wait()
    assert saved is not None, "no mid-stylization checkpoint appeared (or the run ended first)"
    # nothing beside the output yet (no half-written .ply/.json/.png, no temporary files); the checkpoint loads
    assert list(out.parent.iterdir()) == []
    state, meta = read_checkpoint(ckpt)
    assert state["phase"] in ("stylize", "refit") and meta["out"] == str(out.resolve())

    resumed = subprocess.run(_gstyle(*_stylize_args(scene, style, out, *RUN_ARGS, "--resume")), env=env, cwd=ROOT,
                             capture_output=True, text=True, timeout=400)
    assert resumed.returncode == 0, resumed.stdout[-2000:] + resumed.stderr[-2000:]
    assert f"skipped {state['global_step']} of" in resumed.stdout
    assert not ckpt.exists()  # removed after a successful finish
    ref_log, _ = reference.communicate(timeout=400)
    assert reference.returncode == 0, ref_log[-2000:]

    ref, got = (json.loads(p.with_suffix(".json").read_text()) for p in (ref_out, out))
    assert got["resumed"]["skipped_steps"] == state["global_step"] and ref["resumed"] is None
    assert got["gaussians_after"] == ref["gaussians_after"] <= 420
    assert any("reduced" in r for r in ref["decisions"]["reductions"])  # the cap was reported in OUT.json
    for when in ("initial", "final"):
        for key, value in ref["quality"][when].items():
            assert got["quality"][when][key] == pytest.approx(value, rel=REL_TOL, abs=1e-9), (when, key)
    a, b = load_scene(ref_out)[0], load_scene(out)[0]
    np.testing.assert_allclose(b.sh_dc, a.sh_dc, atol=1e-5)
    np.testing.assert_allclose(b.means, a.means, atol=1e-5)


@pytest.mark.slow
def test_a_gpu_failure_keeps_the_run_and_the_cpu_goes_on_from_it(inputs, tmp_path, capsys, monkeypatch):
    """A GPU that fails mid-stylization (a stand-in: every engine not set to "cpu" runs out of memory at its fifth
    stylize step): one line that says where the run is kept, and ``--device cpu --resume`` goes on from there."""
    from gstyle_core.device import DeviceMemoryError
    from gstyle_core.engine.stylizer import Stylizer

    scene, style, cache = inputs
    _vgg_into(cache)
    step = Stylizer.step

    def failing_on_the_gpu(engine):
        if engine.settings.device != "cpu" and engine.phase == "stylize" and engine.phase_step == 4:
            raise DeviceMemoryError("NVIDIA H100 (a stand-in) ran out of memory in stylize: take a lighter preset, or "
                                    "compute on the CPU (--device cpu)")
        return step(engine)

    monkeypatch.setattr(Stylizer, "step", failing_on_the_gpu)
    out = tmp_path / "out" / "o.ply"
    args = _stylize_args(scene, style, out, "--working-width", "48", "--threads", "1", "--checkpoint-every", "0")
    assert run(args) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]  # (the progress bar's lines before it)
    assert err.startswith("gstyle stylize: error: NVIDIA H100 (a stand-in) ran out of memory") and \
        err.endswith("the same command with --device cpu --resume goes on from there"), err
    state, _meta = read_checkpoint(stylize_checkpoint_path(out))
    assert state["phase"] == "stylize" and state["phase_step"] == 4 and not out.exists()
    assert run([*args, "--device", "cpu", "--resume"]) == 0
    assert f"skipped {state['global_step']} of" in capsys.readouterr().out
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["resumed"]["skipped_steps"] == state["global_step"] and summary["settings"]["device"] == "cpu"


class RandomWeightsPull:
    """Stand-in objective whose CLIP term draws random numbers (like CLIP's random crops) from its own generator."""

    def __init__(self, style, settings):
        from types import SimpleNamespace

        import torch

        self.target = torch.as_tensor(np.asarray(style).reshape(-1, 3).mean(0))
        self.loss = SimpleNamespace(clip_term=SimpleNamespace(generator=torch.Generator().manual_seed(7)))

    def set_weights(self, weights):
        pass

    def __call__(self, image, content, view, coverage=None):
        import torch

        w = torch.rand(3, generator=self.loss.clip_term.generator)
        loss = (w * (image.reshape(-1, 3).mean(0) - self.target) ** 2).sum()
        return loss, {"nnfm": float(loss.detach())}


def test_in_memory_resume_restores_the_objective_random_state():
    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer
    from tests.synthetic import ring_cameras

    def engine():
        settings = resolve_settings("preview", "forward", 4, max_views=4, epochs=4, min_steps=0, refit_iterations=2,
                                    split_at=(0.5,), working_width=32, preprocess_rounds=0)
        style = np.zeros((8, 8, 3), np.float32)
        style[..., 0] = 1.0
        return Stylizer(blob_scene(120, seed=4), ring_cameras(4), style, settings, objective_factory=RandomWeightsPull)

    a = engine()
    while a.phase != "stylize" or a.phase_step < 3:
        a.step()
    state = a.state_dict()
    b = engine()
    b.load_state_dict(state)
    a.run()
    b.run()
    assert np.array_equal(a.snapshot()["colors"], b.snapshot()["colors"])
