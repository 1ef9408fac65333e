"""An engine error in the studio (issue #48): the worker's line says where the run stopped (phase, step) and what
failed, and names the crash log with the traceback; nothing claims to run afterwards (Resume stays Resume with no
ETA, Refine does not wait for steps that never come); Continue goes on from the last finished step. A real small
engine in a worker thread, its stylization's third step made to raise."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
import torch
from fakes import BUILT, keep_small_stylizer

from app.worker import ThreadWorkerBridge
from gstyle_core.engine.phases import Stylize
from gstyle_core.engine.stylizer import Stylizer

W, H = 700, 1300  # the studio window of the panel test: tall enough for the whole panel
LINE = re.compile(r"the run stopped in phase (\w+) at step (\d+) of \d+: RuntimeError: injected into the "
                  r"stylization; traceback in (\S+\.log)")


def fail_third_stylize_step(monkeypatch) -> None:
    """``Stylize.step`` raises a two-line ``RuntimeError`` at its third call (the others run)."""
    original, calls = Stylize.step, [0]

    def step(self):
        calls[0] += 1
        if calls[0] == 3:
            raise RuntimeError("injected into the stylization\nsecond line of the message")
        return original(self)

    monkeypatch.setattr(Stylize, "step", step)


def record_loads(monkeypatch) -> list:
    """Each ``load_state_dict``'s engine, its colours and its step just after the load (a Continue's)."""
    load, loaded = Stylizer.load_state_dict, []

    def recording_load(engine, state):
        load(engine, state)
        loaded.append((engine, engine.c_s.clone(), engine.global_step))

    monkeypatch.setattr(Stylizer, "load_state_dict", recording_load)
    return loaded


def check_failure(state, failed, cache: Path) -> None:
    """The error is one line naming the failed engine's phase and step (one past its last finished one) and its
    crash log (in the cache folder, with the traceback and the whole message); nothing steps."""
    found = LINE.fullmatch(state.error)
    assert found, state.error
    assert found.group(1) == failed.phase and int(found.group(2)) == failed.global_step + 1
    log = Path(found.group(3))
    assert log.parent == cache / "crashes"
    text = log.read_text()
    assert "Traceback (most recent call last)" in text and "second line of the message" in text
    assert "studio worker: the run stopped in phase" in text and "all controls: lambda_clip=" in text
    assert state.failed and state.paused and not state.stepping
    assert state.continue_from == failed.global_step == state.last_report["step"]


def test_after_an_engine_error_nothing_claims_to_run_and_continue_goes_on(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("GSTYLE_CACHE", str(cache))
    loaded = record_loads(monkeypatch)
    BUILT.clear()
    b = ThreadWorkerBridge(keep_small_stylizer, {"n": 80})
    with monkeypatch.context() as patch:
        fail_third_stylize_step(patch)
        b.start()
        try:
            assert b.wait_until(lambda s: s.failed or s.done, 120), b.state.error
            failed = BUILT[-1]
            check_failure(b.state, failed, cache)
            colours, reports = failed.c_s.clone(), b.state.reports_received
            b.resume()  # acknowledged as still paused: the worker would sit idle
            b.step_once()  # no retry of the failed step on the failed engine
            b.refine()  # refused: its level would wait for steps that never come
            assert b.wait_until(lambda s: "stopped at an error" in s.refine_note, 10), b.state.refine_note
            time.sleep(0.3)
            b.poll()
            assert b.state.paused and not b.state.stepping and not b.state.done
            assert b.state.reports_received == reports and b.state.failed
        except BaseException:
            b.quit(timeout=30)
            raise
    try:
        b.continue_run()  # the failure injected no more: the run goes on from its last finished step
        assert not b.state.failed and b.state.error is None
        assert b.wait_until(lambda s: s.done or s.error, 120) and b.state.error is None, b.state.error
        engine, at_load, step = loaded[-1]
        assert engine is BUILT[-1] is not failed and step == failed.global_step == b.state.resumed["step"]
        assert torch.equal(at_load, colours)  # the colours the last finished step left
        assert b.state.last_report["step"] > step and not b.state.paused
    finally:
        assert b.quit(timeout=30)


def test_the_panel_disables_what_cannot_work_and_offers_continue(window, monkeypatch, tmp_path):
    pytest.importorskip("imgui_bundle")
    from fakes import small_studio
    from imgui_driver import studio_driver

    app = small_studio(window, monkeypatch, tmp_path)
    try:
        with monkeypatch.context() as patch:
            fail_third_stylize_step(patch)
            app.engine.start()
            assert app.engine.bridge.wait_until(lambda s: s.failed or s.done, 120), app.engine.bridge.state.error
        driver = studio_driver(window, monkeypatch, app)
        driver.frame()
        p, step = app.panel, BUILT[-1].global_step
        assert p.failed and not p.running and p.eta_seconds is None and "(stopped at an error)" in p.phase
        reason = f"The run stopped at an error (above): Continue goes on from step {step}, the last finished one"
        assert driver.recorder.find("Resume###pause").tooltip.startswith(reason)
        assert driver.click("Resume###pause") == [] and driver.click("Step") == []  # disabled
        refine = [w.path for w in driver.recorder.widgets if w.path.startswith("Refine -> ")]
        assert refine and driver.click(refine[0]) == []  # disabled too
        commands = driver.click(f"Continue from step {step}")
        assert [c.name for c in commands] == ["continue_run"]
        assert app.engine.bridge.wait_until(lambda s: s.resumed is not None or s.error, 60), \
            app.engine.bridge.state.error
        driver.frame()
        assert app.panel.status == f"continued on the CPU at step {step}" and not app.panel.failed
        assert app.engine.bridge.wait_until(lambda s: s.done or s.error, 120) and app.engine.bridge.state.error is None
    finally:
        assert app.close(timeout=60)


def test_a_bug_in_the_worker_loop_itself_is_one_line_and_the_worker_is_said_gone(tmp_path, monkeypatch):
    from fakes import make_fake_engine

    from app.engine_host import EngineHost
    from app.studio_sync import stopped_reason

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    handle = EngineHost.handle

    def broken(self, command, arg):
        if command == "pause":
            raise AssertionError("injected into the worker's loop\nsecond line of the message")
        return handle(self, command, arg)

    monkeypatch.setattr(EngineHost, "handle", broken)
    b = ThreadWorkerBridge(make_fake_engine, {"n": 8})
    b.start()
    try:
        assert b.wait_until(lambda s: s.reports_received >= 2, 30), b.state.error
        b.pause()
        assert b.wait_until(lambda s: not s.alive, 30)
        found = re.fullmatch(r"the engine worker stopped: AssertionError: injected into the worker's loop; "
                             r"traceback in (\S+\.log)", b.state.error or "")
        assert found, b.state.error
        assert "second line of the message" in Path(found.group(1)).read_text()
        assert not b.state.stepping and stopped_reason(b.state).startswith("The engine is not running: Restart")
    finally:
        b.quit(timeout=5)


def test_space_does_nothing_while_pause_and_resume_cannot_work():
    pytest.importorskip("imgui_bundle")
    from app.keys import KeyPress
    from app.panels.draw import _shortcut
    from app.panels.state import PanelState

    space = KeyPress("space")
    assert [c.name for c in _shortcut(PanelState(paused=True), space)] == ["resume"]
    assert _shortcut(PanelState(paused=True, stopped="The run stopped at an error (above): ..."), space) == []


def test_a_finished_run_offers_no_pause_or_step_and_says_why():
    from fakes import make_fake_engine

    from app.studio_sync import stopped_reason

    b = ThreadWorkerBridge(make_fake_engine, {"n": 8, "total_steps": 3})
    b.start()
    try:
        assert b.wait_until(lambda s: s.done or s.error, 30), b.state.error
        assert b.state.alive and not b.state.stepping
        assert stopped_reason(b.state).startswith("The run is done: Refine carries it on")
    finally:
        b.quit(timeout=5)
