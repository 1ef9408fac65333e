"""What the end-to-end test (``test_app_end_to_end.py``) installs in the studio it starts as a separate process:
a small real engine (``fakes.make_small_stylizer``: the real ``Stylizer`` on ``blob_scene(150, seed=5)``, a cheap
objective) and, after every frame with the panel, a map of the panel written to ``$GSTYLE_TEST_WIDGETS`` (JSON: every
widget's kind, id path and rectangle in window pixels, the texts, and the studio's state), so that the test clicks
widgets where they are drawn with real X input."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

MAP_EVERY = 0.2  # seconds between two maps


def studio_state(app) -> dict:
    """What the test checks besides the pixels: the engine's state, the scene shown and whether it is a result."""
    bridge = app.engine.bridge
    state = None if bridge is None else bridge.state
    return {"engine": None if state is None else {"alive": state.alive, "done": state.done, "error": state.error,
                                                   "snapshots": state.snapshots_received,
                                                   "reports": state.reports_received,
                                                   "snapshot_phase": state.snapshot.get("phase"),
                                                   "colour_version": state.snapshot.get("colour_version"),
                                                   "resumed": state.resumed, "autosaved": state.autosaved,
                                                   "pid": getattr(bridge._process, "pid", None)},  # noqa: SLF001
            "scene": None if app.session.loaded is None else str(app.session.loaded.path),
            "result": None if app.session.result is None else str(app.session.result.summary),
            "save_folder": str(app.outputs.save_folder), "gaussians": app.views.stylized.count,
            "status": app.panel.status, "time": time.time()}


def install() -> None:
    """Swap the engine factory for the small engine and record the panel (call before ``app.main.main``)."""
    import fakes
    import imgui_driver
    from pytest import MonkeyPatch

    import app.engine_factory as factory
    from app.studio import StudioApp

    factory.make_stylizer = fakes.make_small_stylizer
    recorder = imgui_driver.install(MonkeyPatch())
    target = Path(os.environ["GSTYLE_TEST_WIDGETS"])
    original = StudioApp.frame
    last = [0.0]

    def frame(self, fbo, with_ui: bool = True):
        recorder.widgets.clear()
        recorder.texts.clear()
        commands = original(self, fbo, with_ui)
        now = time.monotonic()
        if with_ui and now - last[0] >= MAP_EVERY:
            last[0] = now
            data = {"widgets": [[w.kind, w.path, list(w.rect)] for w in recorder.widgets],
                    "texts": list(recorder.texts), "state": studio_state(self)}
            partial = target.with_suffix(".partial")
            partial.write_text(json.dumps(data))
            os.replace(partial, target)
        return commands

    StudioApp.frame = frame
