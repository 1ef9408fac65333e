"""SOG scenes through the engine: ``gstyle stylize`` of a .sog bundle (the real engine's smallest run,
``GSTYLE_SMOKE``) and ``gstyle batch`` over a bundle and a SOG folder (the stand-in engine of the batch tests)."""

from __future__ import annotations

import json

import pytest
from batch_worker import use_tiny_engine
from synthetic import blob_scene
from test_batch import painting

from gstyle_core.cli import run
from gstyle_core.io import load_scene, save_scene


@pytest.mark.slow
def test_gstyle_stylize_reads_a_sog_bundle(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("GSTYLE_SMOKE", "1")  # one split round, a few steps at 32 px: about 10 s here
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    save_scene(blob_scene(400, seed=1, sh_degree=1), tmp_path / "blob.sog")
    out = tmp_path / "out.ply"
    assert run(["stylize", str(tmp_path / "blob.sog"), "--out", str(out), "--checkpoint-every", "0"]) == 0
    assert "stylize: 400 Gaussians" in capsys.readouterr().out
    assert load_scene(out)[0].count >= 400
    summary = json.loads((tmp_path / "out.json").read_text())
    assert summary["source_scene"] == str((tmp_path / "blob.sog").resolve())


def test_gstyle_batch_stylizes_sog_bundles_and_folders(tmp_path, monkeypatch):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    built: list = []
    use_tiny_engine(monkeypatch.setattr, built)
    save_scene(blob_scene(40, seed=1), tmp_path / "bundle.sog")
    save_scene(blob_scene(50, seed=2, sh_degree=2), tmp_path / "folder" / "meta.json")
    painting((220, 20, 20)).save(tmp_path / "red.png")
    scenes = [str(tmp_path / "bundle.sog"), str(tmp_path / "folder")]
    argv = ["batch", "--scenes", *scenes, "--styles", str(tmp_path / "red.png"), "--out", str(tmp_path / "batch"),
            "--checkpoint-every", "0", "--jobs", "1"]
    assert run(argv) == 0
    assert [request.scene for request in built] == scenes
    for name in ("bundle__red", "folder__red"):
        assert (tmp_path / "batch" / f"{name}.ply").is_file() and (tmp_path / "batch" / f"{name}.json").is_file()
