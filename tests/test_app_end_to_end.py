"""The studio end to end in a real X window (Xvfb) with real input (xdotool), as issue #35 asks: a run → keep
colours ticked and unticked (the colours back, checked on the scene view's pixels) → Restart → Ctrl+Z (the earlier
result back) → Save As → the saved file reopened (it opens as a result: no engine starts; its settings shown) →
Continue this run (the run kept with the file loads on the original, where it ended).

The studio runs as its own process with ``tests/e2e_hooks.py``: a small real engine (the real ``Stylizer``, a cheap
objective) and a map of what the panel drew (widget rectangles, texts, the studio's state), so that clicks land on
the widgets where they are drawn. Each state's window is kept as ``e2e_<n>_<state>.png`` in the test's folder.
Skipped without Xvfb or xdotool."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from test_app_real_window import TESTS, Studio, display  # noqa: E402, F401  (display: the X server fixture)

from gstyle_core.io import save_scene  # noqa: E402
from tests.synthetic import blob_scene  # noqa: E402

SIZE = (1280, 800)
PANEL_TOP = 24  # the panel window's title bar covers y 0-19: a widget scrolled under it is not clickable
WITH_HOOKS = ("import sys; sys.path.insert(0, sys.argv.pop(1)); import e2e_hooks; e2e_hooks.install(); "
              "from app.main import main; sys.exit(main(sys.argv[1:]))")


class Mapped(Studio):
    """The studio with ``e2e_hooks``: its panel's map read back, widgets clicked by their id path."""

    def __init__(self, x_display: str, tmp: Path, scene: Path, style: Path) -> None:
        self.map_file = tmp / "panel.json"
        super().__init__(x_display, tmp, scene, f"{SIZE[0]}x{SIZE[1]}", "--style", str(style),
                         start=["-c", WITH_HOOKS, str(TESTS), "--engine"],
                         env={"GSTYLE_TEST_WIDGETS": str(self.map_file), "GSTYLE_FILE_DIALOG": "studio"})
        self.shots = 0

    def panel(self) -> dict:
        for _ in range(50):
            try:
                return json.loads(self.map_file.read_text())
            except (OSError, ValueError):
                time.sleep(0.1)
        raise AssertionError("the studio wrote no panel map")

    def wait(self, condition, what: str, timeout: float = 120.0) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            data = self.panel()
            if condition(data):
                return data
            assert self.proc.poll() is None, f"the studio exited while waiting for {what}: {self.proc.stderr.read()}"
            time.sleep(0.3)
        raise AssertionError(f"timed out waiting for {what}; last state {self.panel()['state']}")

    def snapshots(self) -> int:
        return self.panel()["state"]["engine"]["snapshots"]

    def settle(self, what: str, after: int = -1, timeout: float = 120.0) -> dict:
        """Wait until the engine's run has ended, it sent a snapshot after the ``after``-th, and every snapshot it
        sent has reached the view (none new for 3 s; the pointer moves meanwhile, so the studio keeps drawing)."""
        self.wait(lambda d: engine_done(d) and d["state"]["engine"]["snapshots"] > after, what, timeout)
        last, since, deadline = None, time.monotonic(), time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.move(900 + 40 * (int(time.monotonic() * 2) % 2), 60)
            data = self.panel()
            count = data["state"]["engine"]["snapshots"]
            if count != last:
                last, since = count, time.monotonic()
            elif time.monotonic() - since > 3.0:
                return data
            time.sleep(0.3)
        raise AssertionError(f"the snapshots did not settle ({what})")

    def click_widget(self, path: str) -> None:
        """Click the widget drawn with this id path, scrolling the panel (the wheel over it) until it is in view."""
        for _ in range(40):
            widgets = [w for w in self.panel()["widgets"] if w[1] == path]
            assert widgets, f"no widget {path!r} drawn: {[w[1] for w in self.panel()['widgets']]}"
            kind, _, (x0, y0, x1, y1) = widgets[-1]
            if y0 < PANEL_TOP:  # under the panel's title bar, or above it
                self.wheel(4)
            elif y1 > SIZE[1] - 4:
                self.wheel(5)
            else:
                x = x0 + 0.5 * min(x1 - x0, y1 - y0) if kind == "checkbox" else 0.5 * (x0 + x1)
                self.click(x, 0.5 * (y0 + y1))
                return
        raise AssertionError(f"could not scroll {path!r} into view")

    def wheel(self, button: int) -> None:
        """One wheel step over the panel (4: up, 5: down), then a map of the new frame."""
        self.move(200, SIZE[1] // 2)
        self.xdo("click", str(button))
        time.sleep(0.5)

    def scene_view(self, tmp: Path, name: str) -> np.ndarray:
        """The scene view alone (Shift+F12), after the view has settled; the whole window kept for looking at."""
        from PIL import Image

        time.sleep(1.5)
        self.shots += 1
        Image.fromarray(self.grab(SIZE)).save(tmp / f"e2e_{self.shots}_{name}.png")
        return self.screenshot(scene_only=True).astype(np.int16)


def engine_done(data: dict) -> bool:
    """The run has ended and its last snapshot (the one sent once it was done) reached the studio."""
    engine = data["state"]["engine"]
    return engine is not None and engine["done"] and engine["snapshot_phase"] == "done"


def colour_of(img: np.ndarray) -> np.ndarray:
    """The mean colour of the lit pixels: what a result looks like from any viewpoint (a scene opened anew gets a
    view framed for it, so its pixels do not line up with the run's)."""
    lit = img.sum(-1) > 30
    assert lit.sum() > 2000, "the scene is not in the view"
    return img[lit].mean(0)


def differs(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute difference (0–255) over the pixels either image lights."""
    lit = (a.sum(-1) > 30) | (b.sum(-1) > 30)
    assert lit.sum() > 2000, "the scene is not in the view"
    return float(np.abs(a - b)[lit].mean())


@pytest.mark.slow
def test_run_keep_colours_restart_undo_save_as_and_reopen(display, tmp_path):  # noqa: F811
    from PIL import Image

    scene = tmp_path / "blob.ply"
    save_scene(blob_scene(150, seed=5), scene)  # the scene fakes.make_small_stylizer stylizes
    style = tmp_path / "red.png"
    Image.fromarray(np.full((16, 16, 3), (220, 30, 30), np.uint8)).save(style)
    with Mapped(display, tmp_path, scene, style) as studio:
        studio.key("r")
        studio.settle("the first run to end")
        run = studio.scene_view(tmp_path, "run")

        sent = studio.snapshots()
        studio.click_widget("keep colours")
        studio.settle("keep colours ticked", after=sent, timeout=30)
        kept = studio.scene_view(tmp_path, "keep_colours_on")
        assert differs(kept, run) > 3.0, "ticking keep colours did not change the colours"
        sent = studio.snapshots()
        studio.click_widget("keep colours")
        studio.settle("keep colours unticked", after=sent, timeout=30)
        back = studio.scene_view(tmp_path, "keep_colours_off")
        assert differs(back, run) < 0.5, "unticking keep colours did not bring the stylized colours back"

        sent = studio.snapshots()
        studio.click_widget("Restart")
        studio.settle("the restarted run to end", after=sent + 2)
        studio.scene_view(tmp_path, "restarted")

        studio.key("ctrl+z")
        undone = studio.wait(lambda d: d["state"]["result"] is not None, "Ctrl+Z to bring the earlier result back")
        assert undone["state"]["engine"] is None or not undone["state"]["engine"]["alive"]
        earlier = studio.scene_view(tmp_path, "undone")
        assert np.abs(colour_of(earlier) - colour_of(run)).max() < 2.0, "Ctrl+Z did not show the earlier result"

        studio.key("ctrl+shift+s")
        studio.wait(lambda d: any(w[1] == "Save" for w in d["widgets"]), "the Save As browser")
        studio.key("ctrl+a")
        studio.xdo("type", "--delay", "30", "e2e_saved.ply")
        studio.key("Return")
        saved = studio.wait(lambda d: (studio.out / "e2e_saved.ply").is_file(), "Save As to write the file")
        assert (studio.out / "e2e_saved.json").is_file(), saved["state"]
        studio.scene_view(tmp_path, "saved")

        studio.click_widget("Open scene...")
        studio.wait(lambda d: any(w[1] == "Open" for w in d["widgets"]), "the open browser")
        studio.key("ctrl+a")
        studio.xdo("type", "--delay", "30", str(studio.out / "e2e_saved.ply"))
        studio.key("Return")
        reopened = studio.wait(lambda d: d["state"]["scene"] == str(studio.out / "e2e_saved.ply"), "the reopen")
        time.sleep(2.0)
        reopened = studio.panel()
        assert reopened["state"]["result"] is not None, "the saved file did not open as a result"
        assert reopened["state"]["engine"] is None, "opening the saved result started an engine"
        assert any("a stylized result (preset preview" in t for t in reopened["texts"]), reopened["texts"]
        shown = studio.scene_view(tmp_path, "reopened")
        assert np.abs(colour_of(shown) - colour_of(run)).max() < 2.0, "the reopened result is not the one saved"

        studio.click_widget("Continue this run")  # its run was kept (undo's copy, carried by Save As)
        continued = studio.wait(lambda d: d["state"]["engine"] is not None and (d["state"]["engine"]["resumed"]
                                                                               or d["state"]["engine"]["error"]),
                                "Continue to load the run")
        assert continued["state"]["engine"]["error"] is None, continued["state"]["engine"]["error"]
        assert continued["state"]["result"] is None and continued["state"]["scene"] == str(scene.resolve())
        studio.settle("the continued run to show", after=0, timeout=60)
        again = studio.scene_view(tmp_path, "continued")
        assert np.abs(colour_of(again) - colour_of(run)).max() < 2.0, "Continue did not start from the saved run"
