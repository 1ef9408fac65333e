"""The engine worker saves the session on its own (``app/engine_saves.RunSaves.autosave``), and the studio words a
worker that died (``app/child_process.exit_words``); the whole path with a real SIGKILL is
``test_app_worker_killed_x11.py``."""

from __future__ import annotations

import signal
from types import SimpleNamespace

from fakes import FakeEngine

from app.child_process import exit_words
from app.engine_saves import RunSaves
from gstyle_core.engine.checkpoint import read_checkpoint
from gstyle_core.engine.save_pacing import SavePacing


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def fake_host(tmp_path, engine) -> SimpleNamespace:
    sent: list = []
    host = SimpleNamespace(engine=engine, checkpoint_path=str(tmp_path / "session.ckpt"), done=False, config={},
                           fingerprint="f", build_params={}, params={}, level_weights={}, sent=sent,
                           send=lambda kind, payload: sent.append((kind, payload)),
                           steps_done=lambda: engine.steps)
    return host


def test_the_worker_saves_every_interval_of_stepping_and_when_the_run_is_done(tmp_path):
    engine, clock = FakeEngine(n=8, step_seconds=0.0), Clock()
    host = fake_host(tmp_path, engine)
    saves = RunSaves(host)
    saves.pacing = SavePacing(30.0, 0.03, clock)
    for _ in range(3):
        engine.step()
        saves.autosave()  # the first step starts the clock; nothing is due yet
        clock.now += 10.0
    assert host.sent == []
    engine.step()
    saves.autosave()  # 30 s of stepping
    (kind, payload), = host.sent
    assert kind == "autosaved" and payload["step"] == 4 and payload["path"] == host.checkpoint_path
    state, meta = read_checkpoint(host.checkpoint_path)
    assert state["steps"] == 4 and meta["kind"] == "studio"
    engine.step()
    host.done = True  # the run ended between two saves: its end is saved too
    saves.autosave()
    assert [p["step"] for _, p in host.sent] == [4, 5]


def test_a_new_engine_starts_the_clock_again_and_a_failed_save_keeps_the_run_going(tmp_path):
    engine, clock = FakeEngine(n=8, step_seconds=0.0), Clock()
    host = fake_host(tmp_path, engine)
    saves = RunSaves(host)
    saves.pacing = SavePacing(30.0, 0.03, clock)
    saves.autosave()
    clock.now += 29.0
    host.engine = FakeEngine(n=8, step_seconds=0.0)  # restarted: its own 30 s
    saves.autosave()
    clock.now += 29.0
    saves.autosave()
    assert host.sent == []
    host.checkpoint_path = str(tmp_path / "file" / "under_a_file.ckpt")
    (tmp_path / "file").write_text("not a folder")
    clock.now += 2.0
    saves.autosave()
    (kind, line), = host.sent
    assert kind == "error" and line.startswith("saving the session: ") and line.endswith("the run goes on unsaved")


def test_a_killed_worker_is_worded_with_its_signal_and_the_likely_cause():
    capacity = "capacity: all 1,200,000 Gaussians stylized (at most 7,806,516: 21.9 GiB available)"
    assert exit_words(-int(signal.SIGKILL), capacity) == (
        "the engine process was killed (SIGKILL, exit -9): most likely the system ran out of memory; the run's plan: "
        "all 1,200,000 Gaussians stylized (at most 7,806,516: 21.9 GiB available)")
    assert exit_words(-int(signal.SIGKILL)).endswith("most likely the system ran out of memory")
    assert exit_words(-int(signal.SIGSEGV)) == "the engine process was killed (SIGSEGV, exit -11)"
    assert exit_words(3) == "the engine process exited with code 3"
