"""The ``gstyle`` command line: one-line errors, no overwrites, conversions and renders that work."""

from __future__ import annotations

import numpy as np
from PIL import Image

from gstyle_core.cli import run
from gstyle_core.io import load_scene, save_scene
from tests.synthetic import blob_scene


def test_info_convert_render(tmp_path, capsys):
    src = tmp_path / "scene.ply"
    save_scene(blob_scene(200, sh_degree=3), src)
    assert run(["info", str(src)]) == 0
    assert "200" in capsys.readouterr().out
    out = tmp_path / "scene.splat"
    assert run(["convert", str(src), str(out)]) == 0
    scene, report = load_scene(out)
    assert scene.count == 200 and report.format == "splat"
    png = tmp_path / "r.png"
    assert run(["render", str(src), "--out", str(png), "--width", "64"]) == 0
    img = np.asarray(Image.open(png))
    assert img.shape[1] == 64 and img.max() > 0


def test_malformed_input_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.ply"
    header = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\nend_header\n"
    bad.write_bytes(header)
    assert run(["info", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gstyle info: error:") and "\n" not in err and "Traceback" not in err


def test_existing_output_is_not_overwritten_without_force(tmp_path, capsys):
    src = tmp_path / "scene.ply"
    save_scene(blob_scene(20), src)
    out = tmp_path / "out.ply"
    out.write_bytes(b"keep me")
    assert run(["convert", str(src), str(out)]) == 2
    assert out.read_bytes() == b"keep me"
    assert "--force" in capsys.readouterr().err
    assert run(["convert", str(src), str(src), "--force"]) == 2  # never the input itself
    assert run(["convert", str(src), str(out), "--force"]) == 0
    assert load_scene(out)[0].count == 20
