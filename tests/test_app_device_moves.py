"""What the run computes on, in the panel, and moves between devices (issue #36): after the GPU failed (out of
memory, no device, no rasterizer) the studio offers "Continue on the CPU" under the error, and the quality section
offers the GPU where the worker sees one; either way the run goes on from where it was (headless GL window, a real
small engine in a worker thread; stand-ins for the GPU, which this machine lacks)."""

import pytest
import torch

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import BUILT, small_studio, stand_in_gpu_stylizer  # noqa: E402
from imgui_driver import paused_studio_driver, studio_driver  # noqa: E402

from app.panels import Command  # noqa: E402

W, H = 700, 1300  # tall enough for the whole panel


@pytest.mark.slow
def test_the_panel_offers_the_cpu_after_the_gpu_failed_and_the_run_goes_on_there(window, monkeypatch, tmp_path):
    app = small_studio(window, monkeypatch, tmp_path, factory=stand_in_gpu_stylizer)
    try:
        app.engine.start()
        assert app.engine.bridge.wait_until(lambda s: s.error is not None or s.done, 120)
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        assert app.panel.device_failed and "ran out of memory in stylize" in app.panel.error
        assert "slower" in driver.recorder.find("Continue on the CPU").tooltip
        failed, step = BUILT[-1], app.engine.bridge.state.last_report["step"]
        commands = driver.click("Continue on the CPU")
        assert [(c.name, c.args) for c in commands] == [("move_to", {"device": "cpu"})]
        assert app.engine.config["device"] == "cpu"
        assert app.engine.bridge.wait_until(lambda s: s.resumed is not None or s.error, 60), \
            app.engine.bridge.state.error
        driver.frame()
        assert app.panel.status == f"continued on the CPU at step {step}"
        assert BUILT[-1] is not failed and BUILT[-1].settings.device == "cpu"
        assert app.engine.bridge.wait_until(lambda s: s.done or s.error, 120) and app.engine.bridge.state.error is None
        driver.frame()
        assert not app.panel.device_failed and "Continue on the CPU" not in [w.path for w in driver.recorder.widgets]
        app.execute(Command("restart"))  # a restart stays on the CPU
        assert app.engine.bridge.wait_until(lambda s: s.reports_received >= 1 or s.error, 60), \
            app.engine.bridge.state.error
        assert BUILT[-1].settings.device == "cpu" and app.engine.bridge.state.error is None
    finally:
        assert app.close(timeout=60)


def unavailable_gpu_stylizer(device=None, **config):
    """``keep_small_stylizer``, which cannot be built on any device but "cpu" (as where torch sees no GPU)."""
    from fakes import keep_small_stylizer

    from gstyle_core.device import DeviceUnavailable

    if device != "cpu":
        raise DeviceUnavailable("--device cuda: torch sees no CUDA device (a stand-in)")
    return keep_small_stylizer(device=device, **config)


def test_with_no_engine_to_take_over_the_cpu_starts_afresh_and_says_so(window, monkeypatch, tmp_path):
    app = small_studio(window, monkeypatch, tmp_path, factory=unavailable_gpu_stylizer)
    try:
        app.engine.start()
        assert app.engine.bridge.wait_until(lambda s: s.error is not None, 60)
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        assert app.panel.device_failed and "sees no CUDA device" in app.panel.error and not BUILT
        app.execute(Command("move_to", {"device": "cpu"}))
        assert app.panel.status == "moving the run to the CPU ..."
        assert app.engine.bridge.wait_until(lambda s: s.reports_received >= 1 or s.error, 60), \
            app.engine.bridge.state.error
        driver.frame()
        assert app.panel.status == "started afresh on the CPU" and app.panel.error is None
        assert BUILT[-1].settings.device == "cpu"
    finally:
        assert app.close(timeout=60)


def test_a_move_to_a_gpu_that_fails_loses_nothing_and_the_cpu_goes_on(window, monkeypatch, tmp_path):
    """The panel says what the run computes on and offers the GPU where the worker sees one (a stand-in here: this
    machine has none, so the move fails to build); the run's state was handed over first, so Continue on the CPU
    goes on from where the run was moved from."""
    from gstyle_core.engine.stylizer import Stylizer

    monkeypatch.setattr("app.engine_host.available_devices", lambda: ("cpu", "cuda"))
    load, loaded = Stylizer.load_state_dict, []

    def recording_load(engine, state):
        load(engine, state)
        loaded.append(engine.c_s.clone())

    monkeypatch.setattr(Stylizer, "load_state_dict", recording_load)
    app = small_studio(window, monkeypatch, tmp_path)
    try:
        driver = paused_studio_driver(window, monkeypatch, app)
        app.engine.bridge.resume()
        # (a stylize step reported: the last report alone may be past the phase, its steps drained in one poll)
        assert app.engine.bridge.wait_until(lambda s: s.step_times.counts.get("stylize") or s.error, 120)
        app.engine.bridge.pause()
        assert app.engine.bridge.wait_until(lambda s: s.paused, 30)
        driver.frame()
        assert "Computing on: CPU" in driver.recorder.texts and app.panel.devices == ("cpu", "cuda")
        assert "from where the run is, computing on the GPU" in driver.recorder.find("Move to the GPU").tooltip
        moved, step = BUILT[-1], app.engine.bridge.state.last_report["step"]
        colours = moved.c_s.clone()
        commands = driver.click("Move to the GPU")
        assert [(c.name, c.args) for c in commands] == [("move_to", {"device": "cuda"})]
        assert app.engine.config["device"] == "cuda"
        assert app.engine.bridge.wait_until(lambda s: s.error is not None, 60)
        assert torch.equal(moved.c_s, colours)  # a paused run stays paused while it is handed over
        driver.frame()
        assert app.panel.device_failed and "sees no CUDA device" in app.panel.error
        widgets = [w.path for w in driver.recorder.widgets]
        assert "Continue on the CPU" in widgets and not any(w.startswith("Move to") for w in widgets)
        driver.click("Continue on the CPU")
        assert app.engine.bridge.wait_until(lambda s: s.resumed is not None or s.error, 60), \
            app.engine.bridge.state.error
        driver.frame()
        assert app.panel.status == f"continued on the CPU at step {step}"
        assert BUILT[-1] is not moved and torch.equal(loaded[-1], colours)  # the state as handed over
        assert "Computing on: CPU" in driver.recorder.texts
    finally:
        assert app.close(timeout=60)


def test_the_panel_offers_the_gpu_from_elsewhere_and_the_cpu_from_a_gpu():
    from app.panels.quality import move_target
    from app.panels.state import PanelState

    def target(device, devices, failed=False):
        return move_target(PanelState(device=device, devices=devices, device_failed=failed))

    assert target("cpu", ("cpu",)) is None and target("cpu", ("cpu", "cuda")) == "cuda"
    assert target("cuda", ("cpu", "cuda")) == "cpu" and target("mps", ("cpu", "mps")) == "cpu"
    assert target("mps", ("cpu", "cuda", "mps")) == "cuda" and target("cpu", ("cpu", "mps")) is None  # MPS unmeasured
    assert target("", ("cpu", "cuda")) is None and target("cuda", ("cpu", "cuda"), failed=True) is None
