"""Ctrl+C in the terminal that runs ``gstyle-studio`` ends it as the window's close button does: the engine saves the
session, one line on stderr says where, no traceback (from the studio or its engine process), exit status 130."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from synthetic import blob_scene  # noqa: E402

from gstyle_core.engine.checkpoint import read_checkpoint, studio_checkpoint_path  # noqa: E402
from gstyle_core.io import save_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent
# The studio's command line with the engine factory swapped for a fake one that marks its fifth step in a file.
STUDIO = ("import sys; sys.path.insert(0, sys.argv.pop(1)); import fakes, app.engine_factory as factory; "
          "factory.make_stylizer = fakes.make_command_line_engine; from app.main import main; "
          "sys.exit(main(sys.argv[1:]))")


def _headless_window_or_skip() -> None:
    from app.window import DisplayUnavailableError, open_window

    try:
        open_window(64, 48, headless=True).close()
    except DisplayUnavailableError as exc:
        pytest.skip(f"no headless GL window (glfw NULL + EGL): {exc}")


def test_ctrl_c_saves_the_session_and_exits_with_one_line(tmp_path, monkeypatch):
    from PIL import Image

    _headless_window_or_skip()
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    scene, style, stepped = tmp_path / "scene.ply", tmp_path / "style.png", tmp_path / "stepped"
    save_scene(blob_scene(80), scene)
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(style)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.update(GSTYLE_CACHE=str(tmp_path / "cache"), GSTYLE_TEST_STEPPED=str(stepped))
    argv = [sys.executable, "-c", STUDIO, str(TESTS), str(scene), "--style", str(style), "--headless", "--engine",
            "--frames", "1000000", "--size", "160x120", "--output-dir", str(tmp_path / "out")]
    # A session of its own: Ctrl+C in a terminal signals the whole foreground process group, engine process included.
    proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while not stepped.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert stepped.exists(), f"the engine never stepped (exit status {proc.poll()})"
        os.killpg(proc.pid, signal.SIGINT)
        _out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    saved = studio_checkpoint_path(str(scene), str(style))
    assert proc.returncode == 130
    assert err.splitlines() == [f"gstyle-studio: interrupted; session saved to {saved} (gstyle-studio --resume "
                                "continues it)"]
    state, meta = read_checkpoint(saved)
    assert meta["kind"] == "studio" and meta["style"] == str(style) and state["steps"] >= 5


def _studio(tmp_path, *extra: str) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.update(GSTYLE_CACHE=str(tmp_path / "cache"), GSTYLE_TEST_STEPPED=str(tmp_path / "stepped"))
    argv = [sys.executable, "-c", STUDIO, str(TESTS), str(tmp_path / "scene.ply"), "--style", str(tmp_path / "s.png"),
            "--headless", "--engine", "--frames", "1000000", "--size", "160x120", "--output-dir", str(tmp_path / "o"),
            *extra]
    return subprocess.Popen(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _terminate_after(proc: subprocess.Popen, ready) -> str:
    """``kill -TERM`` the studio alone (as a logout or a closing terminal does) once ``ready()``; its stderr."""
    try:
        deadline = time.monotonic() + 180
        while not ready() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert ready(), f"the engine never got there (exit status {proc.poll()})"
        os.kill(proc.pid, signal.SIGTERM)
        return proc.communicate(timeout=120)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


@pytest.mark.slow
def test_sigterm_saves_the_session_and_resume_continues_from_the_step_reached(tmp_path, monkeypatch):
    """Issue #27 item 5: SIGTERM (logout, a closing terminal) saves the session as closing the window does, and
    ``--resume`` continues from the step it reached, not from step 0."""
    from PIL import Image

    _headless_window_or_skip()
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    save_scene(blob_scene(80), tmp_path / "scene.ply")
    Image.fromarray(np.random.default_rng(1).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(tmp_path / "s.png")
    saved = studio_checkpoint_path(str(tmp_path / "scene.ply"), str(tmp_path / "s.png"))
    err = _terminate_after(_studio(tmp_path), (tmp_path / "stepped").exists)
    assert f"session saved to {saved}" in err, err
    reached = read_checkpoint(saved)[0]["steps"]
    assert reached >= 5
    mtime = saved.stat().st_mtime_ns
    proc = _studio(tmp_path, "--resume")
    time.sleep(2.0)  # the engine process starts (it saves on quit whether or not it stepped again)
    err = _terminate_after(proc, lambda: True)
    assert f"session saved to {saved}" in err and saved.stat().st_mtime_ns != mtime, err
    state, _meta = read_checkpoint(saved)
    assert state["resumed_at"] == reached and state["steps"] >= reached
