"""The studio window's size when it opens (issue #35 item 6): as asked, else as left last time, else 80 % of the
screen; a real X window on a private Xvfb screen of 1600 x 1000 checks the whole path."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from app.window_size import DEFAULT_SIZE, MIN_SIZE, initial_size, remember_size, remembered_size

ROOT = Path(__file__).resolve().parents[1]


def test_initial_size_prefers_the_asked_then_the_remembered_then_80_percent_of_the_screen():
    assert initial_size((800, 600), (1500, 900), (1600, 1000)) == (800, 600)
    assert initial_size(None, (1500, 900), (1600, 1000)) == (1500, 900)
    assert initial_size(None, (3000, 2000), (1600, 1000)) == (1600, 1000)  # a larger screen then: no larger now
    assert initial_size(None, None, (1600, 1000)) == (1280, 800)
    assert initial_size(None, None, None) == DEFAULT_SIZE
    assert initial_size(None, (100, 50), (1600, 1000)) == MIN_SIZE


def test_the_size_is_kept_in_the_cache_folder_and_a_broken_file_is_ignored(tmp_path, monkeypatch):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path))
    assert remembered_size() is None
    remember_size((1400, 900))
    assert remembered_size() == (1400, 900)
    (tmp_path / "window.json").write_text("{not json")
    assert remembered_size() is None


OPEN_TWICE = """
from app.window import open_window  # first: imgui_bundle points glfw at its own libglfw
import glfw
w = open_window()
print(*glfw.get_window_size(w.handle))
glfw.set_window_size(w.handle, 1100, 700)
for _ in range(20):
    glfw.poll_events()
w.close()
w = open_window()
print(*glfw.get_window_size(w.handle))
w.close()
w = open_window(640, 480)
w.close()
"""


def test_a_real_window_opens_at_80_percent_of_the_screen_and_then_as_it_was_left(tmp_path, monkeypatch):
    from xsession import start_xvfb

    try:
        server = start_xvfb((1600, 1000))
    except RuntimeError as exc:
        pytest.skip(str(exc))
    try:
        env = {**os.environ, "DISPLAY": server.display, "GSTYLE_CACHE": str(tmp_path)}
        env.pop("WAYLAND_DISPLAY", None)
        out = subprocess.run([sys.executable, "-c", OPEN_TWICE], cwd=ROOT, env=env, capture_output=True, text=True,
                             timeout=120)
    finally:
        server.stop()
    assert out.returncode == 0, out.stderr
    first, second = (tuple(map(int, line.split())) for line in out.stdout.splitlines())
    assert first == (1280, 800) and second == (1100, 700)
    assert (tmp_path / "window.json").exists()  # the asked-for 640 x 480 was not kept over it
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path))
    assert remembered_size() == (1100, 700)
