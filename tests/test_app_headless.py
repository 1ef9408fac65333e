"""``gstyle-studio --headless``: the same frame loop on glfw's NULL platform + EGL, last frame written as PNG."""

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from synthetic import blob_scene, ring_cameras  # noqa: E402

import app.open_files as open_files  # noqa: E402
from app.main import main, parse_size  # noqa: E402

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture
def synthetic_loader(monkeypatch):
    """Serve a small synthetic scene instead of reading a file (the loader is another module's job)."""
    scene = blob_scene(1500, sh_degree=1, spread=0.4, scale=0.05)
    cams = ring_cameras(4, width=320, height=240)
    monkeypatch.setattr(open_files, "load_scene_with_cameras",
                        lambda path, cameras: open_files.LoadedScene(path or "synthetic", scene, cams))


def read_png(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def test_headless_run_writes_png(tmp_path, synthetic_loader, capsys):
    out = tmp_path / "shot.png"
    rc = main(["--headless", "--frames", "2", "--size", "320x240", "--screenshot", str(out), "--hide-ui",
               "--output-dir", str(tmp_path)])
    assert rc == 0 and f"wrote {out}" in capsys.readouterr().out
    img = read_png(out)
    assert img.shape == (240, 320, 3)
    centre, corner = img[100:140, 140:180].mean(), img[:10, :10].mean()
    assert centre > 20 and corner < centre  # the blob is in the middle of a black background


def test_headless_compare_with_panel(tmp_path, synthetic_loader):
    out = tmp_path / "ui.png"
    assert main(["--headless", "--frames", "3", "--size", "900x300", "--screenshot", str(out),
                 "--view", "compare", "--camera", "2", "--output-dir", str(tmp_path)]) == 0
    img = read_png(out)
    assert img.shape == (300, 900, 3)
    assert (img[:8, 659:661] > 240).all()  # the divider in the middle of the view beside the 420-px panel


def test_no_display_stylizes_headless_and_writes_before_after(tmp_path, synthetic_loader, monkeypatch, capsys):
    """Without a display the studio still shows its job: a preview stylization, before/after renders (two views,
    640 px each) and a headless screenshot of the stylized result. The stylization itself is ``gstyle stylize``
    (tested in its own files); here a fake writes the stylized scene."""
    import gstyle_core.cli.stylize as cli
    from gstyle_core.io import save_scene

    calls = []

    def fake_stylize(args):
        calls.append(args)
        save_scene(blob_scene(300, seed=5), args.out)
        return 0

    monkeypatch.setattr(cli, "stylize_command", fake_stylize)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "fallback.png"
    assert main(["--size", "160x120", "--screenshot", str(out), "--output-dir", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "cannot open a window" in printed and "stylizing headless" in printed and str(out) in printed
    assert len(calls) == 1 and calls[0].preset == "preview" and calls[0].out == str(tmp_path / "demo_stylized.ply")
    pair = read_png(tmp_path / "demo_before_after.png")
    assert 0 < pair.shape[1] <= 2 * 640 and pair.shape[0] % 2 == 0  # two 640-px views cropped to the scene
    before, after = pair[: pair.shape[0] // 2], pair[pair.shape[0] // 2:]
    assert before.std() > 5 and np.abs(before.astype(int) - after.astype(int)).mean() > 5
    assert read_png(out).shape == (120, 160, 3)


def test_bad_arguments_are_one_line_errors(synthetic_loader, capsys):
    with pytest.raises(SystemExit):
        parse_size("800by600") if False else main(["--size", "800by600"])
    assert "size must look like 800x600" in capsys.readouterr().err
    assert main(["--headless", "--frames", "0"]) == 2
    assert main(["--headless", "--camera", "9", "--frames", "1"]) == 2
    assert "--camera must be 1..4" in capsys.readouterr().err


def test_real_scene_file(tmp_path):
    scene = DATA / "scenes" / "ply_3dgs" / "cvlab_epfl_pc_short.ply"
    if not scene.is_file():
        pytest.skip(f"shared test data not found at {scene}")
    try:
        from gstyle_core.io import load_scene  # noqa: F401
    except ImportError as exc:
        pytest.skip(f"gstyle_core.io.load_scene not available yet: {exc}")
    out = tmp_path / "real.png"
    assert main([str(scene), "--headless", "--frames", "1", "--size", "320x240", "--screenshot", str(out),
                 "--hide-ui", "--output-dir", str(tmp_path)]) == 0
    assert read_png(out).max() > 0


@pytest.fixture
def xvfb_display(monkeypatch):
    """A private 640x480 Xvfb server on a free display (``xsession.start_xvfb``), stopped afterwards; skipped when
    Xvfb is not installed."""
    from xsession import start_xvfb

    try:
        server = start_xvfb((640, 480))
    except RuntimeError as exc:
        pytest.skip(str(exc))
    monkeypatch.setenv("DISPLAY", server.display)
    yield server.display
    server.stop()


def test_real_window_under_xvfb(tmp_path, synthetic_loader, xvfb_display):
    out = tmp_path / "window.png"
    assert main(["--frames", "3", "--size", "320x240", "--screenshot", str(out), "--no-engine", "--hide-ui",
                 "--fps", "120", "--output-dir", str(tmp_path)]) == 0
    img = read_png(out)
    assert img.shape == (240, 320, 3) and img[100:140, 140:180].mean() > 20


def test_window_module_opens_headless_in_a_fresh_process():
    """Import order matters (imgui_bundle before glfw); a fresh interpreter catches a reordered import."""
    import os
    import subprocess
    import sys

    code = "from app.window import open_window\nw = open_window(64, 64, headless=True)\nw.close()\nprint('ok')"
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).resolve().parents[1], env=env,
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr[-500:]


def test_missing_scene_is_a_one_line_error(tmp_path, capsys):
    assert main([str(tmp_path / "nope.ply"), "--headless", "--frames", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"gstyle-studio: scene file not found: {tmp_path / 'nope.ply'}"
