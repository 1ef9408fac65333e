"""A run survives its worker (issue #65 item 1), in a real X window (Xvfb) with real input (xdotool): the engine
process saves the session on its own while it steps; killed with SIGKILL (as the kernel's out-of-memory killer does),
the panel says why and offers *Resume from step K*; Ctrl+S saves what the view shows at once; Space goes on from step
K; and ``gstyle-studio --resume`` says in the terminal from which step it went on.

The studio runs as its own process with ``tests/e2e_hooks.py`` (the panel's map) and a fake engine that steps for ever
(``fakes.make_slow_engine``); the worker's own saves come every second here (``GSTYLE_AUTOSAVE_SECONDS``). The
window at the offer is kept as ``killed.png`` in the test's folder. Skipped without Xvfb or xdotool."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from test_app_end_to_end import SIZE, Mapped  # noqa: E402
from test_app_real_window import ROOT, TESTS, Studio, display  # noqa: E402, F401  (display: the X server fixture)

from gstyle_core.engine.checkpoint import read_checkpoint, studio_checkpoint_path  # noqa: E402
from gstyle_core.io import save_scene  # noqa: E402
from tests.synthetic import blob_scene  # noqa: E402

SLOW_ENGINE = ("import sys; sys.path.insert(0, sys.argv.pop(1)); import e2e_hooks; e2e_hooks.install(); "
               "import fakes, app.engine_factory as factory; factory.make_stylizer = fakes.make_slow_engine; "
               "from app.main import main; sys.exit(main(sys.argv[1:]))")


class Killable(Mapped):
    """The mapped studio (``test_app_end_to_end.Mapped``) with the slow fake engine and saves every second."""

    def __init__(self, x_display: str, tmp: Path, scene: Path, style: Path) -> None:
        self.map_file, self.shots = tmp / "panel.json", 0
        Studio.__init__(self, x_display, tmp, scene, f"{SIZE[0]}x{SIZE[1]}", "--style", str(style),
                        start=["-c", SLOW_ENGINE, str(TESTS), "--engine"],
                        env={"GSTYLE_TEST_WIDGETS": str(self.map_file), "GSTYLE_AUTOSAVE_SECONDS": "1"})


def engine(data: dict) -> dict:
    return data["state"]["engine"] or {}


def resume_offer(data: dict) -> str | None:
    """The label of the *Resume from step K* button, if the panel drew one."""
    return next((w[1] for w in data["widgets"] if w[1].startswith("Resume from step")), None)


def resumed_line(proc: subprocess.Popen, timeout: float) -> str:
    """The first line ``proc`` prints that tells of a resume ("" if none within ``timeout`` s)."""
    found: list[str] = []

    def read() -> None:
        for line in proc.stdout:
            if "resumed" in line:
                found.append(line.strip())
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout)
    return found[0] if found else ""


@pytest.mark.slow
def test_a_killed_worker_keeps_the_run_and_the_view(display, tmp_path, monkeypatch):  # noqa: F811
    from PIL import Image

    scene, style = tmp_path / "blob.ply", tmp_path / "red.png"
    save_scene(blob_scene(64, seed=5), scene)
    Image.fromarray(np.full((16, 16, 3), (220, 30, 30), np.uint8)).save(style)
    with Killable(display, tmp_path, scene, style) as studio:
        data = studio.wait(lambda d: engine(d).get("autosaved") is not None and engine(d).get("reports", 0) > 40,
                           "the worker's own save", timeout=90)
        os.kill(engine(data)["pid"], signal.SIGKILL)
        data = studio.wait(resume_offer, "the offer to resume", timeout=30)
        Image.fromarray(studio.grab(SIZE)).save(tmp_path / "killed.png")
        error = engine(data)["error"]
        assert "killed (SIGKILL, exit -9): most likely the system ran out of memory" in error, error
        step = int(resume_offer(data).rsplit(" ", 1)[1])
        assert not any(w[1] == "Resume last session" for w in data["widgets"])  # one way on, the right one
        assert step > 0 and step == engine(data)["autosaved"]["step"]

        studio.key("ctrl+s")  # what the view shows, at once, with no engine
        saved = studio.wait(lambda d: d["state"]["status"].startswith("saved what the view shows"), "the view saved")
        written = Path(saved["state"]["status"].split(" to ", 1)[1].split(" (kept as", 1)[0])
        assert written.is_file() and written.with_suffix(".json").is_file(), saved["state"]["status"]

        studio.key("space")
        data = studio.wait(lambda d: engine(d).get("alive") and (engine(d).get("resumed") or {}).get("step"),
                           "Space to resume", timeout=60)
        assert engine(data)["resumed"]["step"] == step
        assert resume_offer(data) is None

    monkeypatch.setenv("GSTYLE_CACHE", studio.env["GSTYLE_CACHE"])  # the studio's cache folder
    session = studio_checkpoint_path(str(scene), str(style))
    reached = read_checkpoint(session)[0]["steps"]  # the terminated studio saved its session as it closed
    env = {**studio.env, "GSTYLE_AUTOSAVE_SECONDS": "1"}
    env.pop("DISPLAY", None)
    argv = [sys.executable, "-c", SLOW_ENGINE, str(TESTS), "--engine", str(scene), "--style", str(style), "--resume",
            "--headless", "--frames", "1000000", "--size", "160x120", "--output-dir", str(tmp_path / "o")]
    proc = subprocess.Popen(argv, cwd=ROOT, env={**env, "GSTYLE_TEST_WIDGETS": str(tmp_path / "headless.json")},
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        line = resumed_line(proc, 90)
    finally:
        proc.terminate()
        proc.communicate(timeout=60)
    assert line == f"gstyle-studio: resumed the last session at step {reached}", line
