"""After the GPU failed (out of memory, no device, no rasterizer), the studio offers "Continue on the CPU" under the
error, and the run goes on there from where it stopped (issue #36; headless GL window, a real small engine in a
worker thread whose stand-in GPU runs out of memory)."""

import pytest

pytest.importorskip("imgui_bundle")
pytest.importorskip("moderngl")

from fakes import BUILT, small_studio, stand_in_gpu_stylizer  # noqa: E402
from imgui_driver import studio_driver  # noqa: E402

from app.panels import Command  # noqa: E402

W, H = 700, 1300  # tall enough for the whole panel


def test_the_panel_offers_the_cpu_after_the_gpu_failed_and_the_run_goes_on_there(window, monkeypatch, tmp_path):
    app = small_studio(window, monkeypatch, tmp_path, factory=stand_in_gpu_stylizer)
    try:
        app.start_engine()
        assert app.bridge.wait_until(lambda s: s.error is not None or s.done, 120)
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        assert app.panel.device_failed and "ran out of memory in stylize" in app.panel.error
        assert "slower" in driver.recorder.find("Continue on the CPU").tooltip
        failed, step = BUILT[-1], app.bridge.state.last_report["step"]
        commands = driver.click("Continue on the CPU")
        assert [c.name for c in commands] == ["continue_on_cpu"] and app.engine_config["device"] == "cpu"
        assert app.bridge.wait_until(lambda s: s.resumed is not None or s.error, 60), app.bridge.state.error
        driver.frame()
        assert app.panel.status == f"continued on the CPU at step {step}"
        assert BUILT[-1] is not failed and BUILT[-1].settings.device == "cpu"
        assert app.bridge.wait_until(lambda s: s.done or s.error, 120) and app.bridge.state.error is None
        driver.frame()
        assert not app.panel.device_failed and "Continue on the CPU" not in [w.path for w in driver.recorder.widgets]
        app.execute(Command("restart"))  # a restart stays on the CPU
        assert app.bridge.wait_until(lambda s: s.reports_received >= 1 or s.error, 60), app.bridge.state.error
        assert BUILT[-1].settings.device == "cpu" and app.bridge.state.error is None
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
        app.start_engine()
        assert app.bridge.wait_until(lambda s: s.error is not None, 60)
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        assert app.panel.device_failed and "sees no CUDA device" in app.panel.error and not BUILT
        app.execute(Command("continue_on_cpu"))
        assert app.panel.status.startswith("continuing on the CPU")
        assert app.bridge.wait_until(lambda s: s.reports_received >= 1 or s.error, 60), app.bridge.state.error
        driver.frame()
        assert app.panel.status == "started afresh on the CPU" and app.panel.error is None
        assert BUILT[-1].settings.device == "cpu"
    finally:
        assert app.close(timeout=60)
