"""``gstyle cache``: lists what the cache folder holds with sizes; ``--clear [--checkpoints-only]`` empties it."""

from __future__ import annotations

import torch

from gstyle_core.cli import run
from gstyle_core.engine.checkpoint import save_checkpoint, stylize_checkpoint_path
from gstyle_core.style.vgg import CACHE_FILE


def test_cache_lists_sizes_and_clears(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "cache"
    monkeypatch.setenv("GSTYLE_CACHE", str(cache))
    assert run(["cache"]) == 0
    assert "(empty)" in capsys.readouterr().out
    cache.mkdir()
    (cache / CACHE_FILE).write_bytes(b"w" * 3 * 1024 * 1024)
    ckpt = save_checkpoint(stylize_checkpoint_path(tmp_path / "out.ply"),
                           {"phase": "stylize", "global_step": 42, "c_s": torch.zeros(10, 3)},
                           {"kind": "stylize", "out": str(tmp_path / "out.ply")})
    (ckpt.parent / "broken.ckpt").write_bytes(b"\x00" * 10)

    assert run(["cache"]) == 0
    out = capsys.readouterr().out
    assert "3.0 MiB  vgg16_caffe_conv3.pt  (converted VGG-16 weights)" in out
    assert f"{ckpt.name}: stylize {tmp_path / 'out.ply'}: phase stylize, step 42" in out
    assert "broken.ckpt: unusable:" in out and "numba compiled kernels" in out

    assert run(["cache", "--checkpoints-only"]) == 2
    assert "--clear" in capsys.readouterr().err
    assert run(["cache", "--clear", "--checkpoints-only"]) == 0
    assert "removed 2 checkpoints" in capsys.readouterr().out
    assert not ckpt.parent.exists() and (cache / CACHE_FILE).is_file()
    assert run(["cache", "--clear"]) == 0
    assert "removed 1 cache entries" in capsys.readouterr().out
    assert list(cache.iterdir()) == []
