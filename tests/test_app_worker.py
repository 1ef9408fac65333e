"""Worker bridge with the fake engine in a spawned process."""

import os
import re
import time
from pathlib import Path

import pytest
import torch
from fakes import FakeReport, make_fake_engine

from app.child_process import worker_torch_threads
from app.engine_host import report_to_dict
from app.worker import ThreadWorkerBridge, WorkerBridge
from gstyle_core.errors import one_line_error


@pytest.fixture
def bridge_factory(started_bridges):
    """A started ``WorkerBridge`` (a spawned process) on the fake engine built from the keywords."""
    return lambda **config: started_bridges(WorkerBridge, make_fake_engine, config)


def test_pause_really_stops_colour_updates_and_resume_continues(bridge_factory):
    b = bridge_factory(n=32)
    assert b.wait_until(lambda s: s.snapshots_received >= 5, 60), b.state.error
    b.pause()
    assert b.wait_until(lambda s: s.paused, 10)
    time.sleep(0.1)
    b.poll()
    version = b.state.snapshot["colour_version"]
    reports = b.state.last_report["step"]
    time.sleep(0.4)
    b.poll()
    assert b.state.snapshot["colour_version"] == version
    assert b.state.last_report["step"] == reports
    b.step_once()
    assert b.wait_until(lambda s: s.snapshot["colour_version"] == version + 1, 10)
    b.resume()
    assert b.wait_until(lambda s: s.snapshot["colour_version"] > version + 3, 10)


def test_lambda_change_reaches_the_engine(bridge_factory):
    b = bridge_factory(n=16)
    assert b.wait_until(lambda s: s.ready, 60)
    b.set_params(lambda_clip=2.5, lr=0.01)
    assert b.wait_until(lambda s: s.snapshot.get("params", {}).get("lambda_clip") == 2.5, 10)
    assert b.state.snapshot["params"]["lr"] == 0.01
    assert b.state.params["lambda_clip"] == 2.5


def test_raising_engine_is_reported_and_restart_works(bridge_factory, tmp_path, monkeypatch):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))  # the worker process writes its crash log there
    b = bridge_factory(n=16, fail_at=3)
    assert b.wait_until(lambda s: s.error is not None, 60)
    # where (the fake tells its phase and step by its reports), what (the message's first line), the crash log
    line = re.fullmatch(r"the run stopped in phase stylize at step 3: RuntimeError: fake engine failure; "
                        r"traceback in (\S+\.log)", b.state.error)
    assert line, b.state.error
    assert "second line" in Path(line.group(1)).read_text() and Path(line.group(1)).parent == tmp_path / "cache" / \
        "crashes"
    assert not b.state.device_failed  # not the GPU's failure: no CPU to go on on is offered
    assert b.wait_until(lambda s: s.failed, 10) and b.state.continue_from == 2 and not b.state.stepping
    good = b.state.snapshot["colour_version"]
    time.sleep(0.2)
    b.poll()
    assert b.alive and b.state.snapshot["colour_version"] == good <= 2  # nothing from the failed step arrives
    b.restart({"n": 16})  # a config without the failure
    assert b.wait_until(lambda s: s.error is None and s.snapshots_received and s.snapshot["colour_version"] > 5, 30)
    # an unknown parameter is an engine error too, reported as one line
    b.set_params(bogus=1.0)
    assert b.wait_until(lambda s: s.error is not None and "unknown parameters" in s.error, 10)


def test_geometry_only_sent_when_its_version_changes(bridge_factory):
    b = bridge_factory(n=8, grow_every=5)
    assert b.wait_until(lambda s: s.snapshots_received >= 12, 60)
    b.pause()
    b.wait_until(lambda s: s.paused, 10)
    time.sleep(0.1)
    b.poll()
    st = b.state
    assert 1 <= st.geometry_received < st.snapshots_received
    assert st.gt_colours_received == st.geometry_received  # c_gt travels with new geometry only
    assert len(st.snapshot["means"]) == len(st.snapshot["colors"]) == 8 + st.snapshot["geometry_version"]


def test_quit_writes_checkpoint_and_resume_reaches_the_engine(tmp_path, monkeypatch):
    from gstyle_core.engine.checkpoint import read_checkpoint, studio_checkpoint_path

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    path = studio_checkpoint_path(tmp_path / "scene.ply", tmp_path / "style.png")  # what the studio uses
    b = WorkerBridge(make_fake_engine, {"n": 4}, checkpoint_path=path)
    b.start()
    assert b.wait_until(lambda s: s.snapshots_received >= 5, 60)
    b.set_params(lambda_clip=2.5)
    assert b.wait_until(lambda s: s.params.get("lambda_clip") == 2.5, 10)
    assert b.quit(timeout=60) is True  # closing the window: checkpoint, clean exit (torch imported to save)
    assert not b.alive and b.state.checkpoint == str(path)
    state, meta = read_checkpoint(path)
    assert state["steps"] >= 5 and meta["kind"] == "studio" and meta["params"]["lambda_clip"] == 2.5

    resumed = WorkerBridge(make_fake_engine, {"n": 4}, resume_from=path, start_paused=True)
    resumed.start()
    try:
        assert resumed.wait_until(lambda s: s.resumed is not None and s.snapshots_received >= 1, 60), \
            resumed.state.error
        assert resumed.state.resumed["step"] == state["steps"]
        assert resumed.state.snapshot["colour_version"] == state["steps"]  # the engine's counter came back
        assert resumed.wait_until(lambda s: s.snapshot.get("params", {}).get("lambda_clip") == 2.5, 10)
        assert resumed.state.params["lambda_clip"] == 2.5  # the sliders' values came back too
    finally:
        resumed.quit(timeout=5)


def test_resume_from_a_foreign_checkpoint_is_one_line_and_the_engine_starts_afresh(tmp_path):
    from gstyle_core.engine.checkpoint import save_checkpoint

    path = save_checkpoint(tmp_path / "other.ckpt", {"phase": "stylize"}, {"kind": "studio"})  # another engine's
    b = WorkerBridge(make_fake_engine, {"n": 8}, resume_from=path)
    b.start()
    try:
        assert b.wait_until(lambda s: s.reports_received >= 2, 120)  # the fresh engine runs
        line = b.state.went_on_after  # the steps since made the error stale: the studio says it once, not in red
        assert b.state.error is None and line.startswith("resume: ") and "starting afresh" in line
        assert "\n" not in line and b.state.resumed is None
    finally:
        b.quit()


def test_a_worker_that_hangs_on_quit_is_killed_within_the_bound(tmp_path):
    b = WorkerBridge(make_fake_engine, {"n": 4, "step_seconds": 60.0, "ignore_sigterm": True},
                     checkpoint_path=tmp_path / "never.ckpt")
    b.start()
    assert b.wait_until(lambda s: s.ready, 60)
    time.sleep(0.3)  # inside the 60 s step now
    t0 = time.monotonic()
    assert b.quit(timeout=1.0) is False
    assert time.monotonic() - t0 < 8.0
    assert not b.alive and "killed" in b.state.error
    assert not (tmp_path / "never.ckpt").exists()


def test_report_and_error_helpers():
    d = report_to_dict(FakeReport("stylize", 3, 10, {"a": 1}, 0.5, 7))
    assert d["phase"] == "stylize" and d["losses"] == {"a": 1.0} and d["gaussians"] == 7
    assert one_line_error(ValueError("x\n  y")) == "ValueError: x y"


def test_a_level_that_changes_the_weights_sends_them_to_the_sliders():
    """A calibrated 360° preview's first level takes other weights (``Stylizer.refine``): the host sends the new
    values, so the panel's sliders show what the level runs with; a level that changes nothing sends none."""
    import queue
    import threading

    from app.engine_host import EngineHost

    class LevelEngine:
        def __init__(self, change: bool) -> None:
            self.params, self.change = {"lambda_nnfm": 200.0, "lambda_edges": 0.0}, change

        def refine(self) -> int:
            if self.change:
                self.params.update(lambda_nnfm=400.0, lambda_edges=4000.0)
            return 64

        def current_params(self) -> dict:
            return dict(self.params)

    for change in (True, False):
        events = queue.Queue()
        host = EngineHost(lambda: None, {}, events, threading.Semaphore(2), None)
        host.engine, host.params = LevelEngine(change), {"lambda_nnfm": 200.0, "lambda_edges": 0.0, "strength": 1.0}
        host.refine()
        sent = [payload for kind, payload in list(events.queue) if kind == "params"]
        if change:
            assert sent == [{"lambda_nnfm": 400.0, "lambda_edges": 4000.0, "strength": 1.0}]
        else:
            assert sent == []


def test_worker_torch_threads_is_one_unless_the_bench_asks(monkeypatch):
    monkeypatch.delenv("GSTYLE_WORKER_THREADS", raising=False)
    assert worker_torch_threads() == 1
    for value, expected in (("4", 4), ("0", 1), ("-2", 1), ("many", 1)):
        monkeypatch.setenv("GSTYLE_WORKER_THREADS", value)
        assert worker_torch_threads() == expected


def test_export_writes_ply_and_summary_or_reports_one_line(bridge_factory, tmp_path):
    b = bridge_factory(n=16)
    assert b.wait_until(lambda s: s.snapshots_received >= 2, 60)
    b.export(tmp_path / "bad.txt")
    assert b.wait_until(lambda s: s.export_failures, 10)
    line = b.state.export_failures[-1]
    assert line.startswith("export: export path must end in") and "\n" not in line
    assert b.state.error is None and not b.state.paused  # a failed export is no engine error: the run goes on
    try:
        from gstyle_core.io import save_scene  # noqa: F401
    except ImportError:
        pytest.skip("gstyle_core.io.save_scene not available yet")
    b.export(tmp_path / "out.ply")
    assert b.wait_until(lambda s: s.exported, 20), b.state.error
    assert (tmp_path / "out.ply").stat().st_size > 0 and (tmp_path / "out.json").is_file()


def test_export_writes_the_web_formats(bridge_factory, tmp_path):
    from gstyle_core.io import load_scene

    b = bridge_factory(n=300)
    assert b.wait_until(lambda s: s.snapshots_received >= 2, 60), b.state.error
    for name, fmt, summary in (("out.spz", "spz-v3", "out.json"),
                               ("web.compressed.ply", "ply-playcanvas-compressed", "web.json"),
                               ("site.sog", "sog-v2 (bundle)", "site.json")):
        b.export(tmp_path / name)
        assert b.wait_until(lambda s, name=name: any(e.endswith(name) for e in s.exported), 20), b.state.error
        scene, report = load_scene(tmp_path / name)
        assert report.format == fmt and scene.count == 300 and scene.sh_degree == 0
        assert (tmp_path / summary).is_file()


@pytest.mark.slow
def test_real_stylizer_resumes_from_its_checkpoint_through_the_bridge(tmp_path):
    from fakes import make_small_stylizer

    from gstyle_core.engine.checkpoint import read_checkpoint

    path = tmp_path / "session.ckpt"
    b = WorkerBridge(make_small_stylizer, {"n": 80}, checkpoint_path=path)
    b.start()
    assert b.wait_until(lambda s: (s.last_report or {}).get("step", 0) >= 8 or s.error, 120), "no progress"
    assert b.state.error is None, b.state.error
    b.quit()
    state, meta = read_checkpoint(path)
    assert state["global_step"] >= 8 and meta["fingerprint"]["scene"]

    again = WorkerBridge(make_small_stylizer, {"n": 80}, resume_from=path)
    again.start()
    try:
        assert again.wait_until(lambda s: s.reports_received >= 1 or s.error, 120)
        assert again.state.error is None, again.state.error
        assert again.state.resumed["step"] == state["global_step"]
        assert again.state.last_report["step"] > state["global_step"]  # counting on from the checkpoint
    finally:
        again.quit()


@pytest.mark.slow
def test_real_stylizer_runs_to_the_end_through_the_bridge():
    pytest.importorskip("gstyle_core.engine.stylizer")
    from fakes import make_small_stylizer

    b = WorkerBridge(make_small_stylizer, {"n": 150})
    b.start()
    try:
        assert b.wait_until(lambda s: s.done or s.error, 120), "engine did not finish"
        st = b.state
        assert st.error is None, st.error
        assert st.last_report["done"] and st.last_report["step"] > 0
        snap = st.snapshot
        assert len(snap["means"]) == len(snap["colors"]) == st.last_report["gaussians"] > 150  # split happened
        assert st.geometry_received >= 2
        assert snap["colors"][:, 0].mean() > snap["colors"][:, 2].mean()  # pulled towards the red style
    finally:
        b.quit()


def test_thread_mode_runs_the_same_protocol_and_stops_cleanly():
    b = ThreadWorkerBridge(make_fake_engine, {"n": 16})
    b.start()
    try:
        assert b.wait_until(lambda s: s.snapshots_received >= 3, 30), b.state.error
        b.set_params(lambda_nnfm=7.0)
        assert b.wait_until(lambda s: (s.params or {}).get("lambda_nnfm") == 7.0, 10)
        b.pause()
        assert b.wait_until(lambda s: s.paused, 10)
        time.sleep(0.1)
        b.poll()
        version = b.state.snapshot["colour_version"]
        time.sleep(0.3)
        b.poll()
        assert b.state.snapshot["colour_version"] == version  # paused: no colour updates
    finally:
        assert b.quit(timeout=10)
    assert not b.alive


def test_thread_mode_leaves_the_process_environment_alone(monkeypatch):
    """A worker thread must not write NUMBA_NUM_THREADS into its host process: numba re-reads the environment on
    every compile and raises once it differs from the pool it launched (CI failed so on a cold kernel cache)."""
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    b = ThreadWorkerBridge(make_fake_engine, {"n": 16})
    b.start()
    try:
        assert b.wait_until(lambda s: s.snapshots_received >= 1, 30), b.state.error
    finally:
        assert b.quit(timeout=10)
    assert "NUMBA_NUM_THREADS" not in os.environ


def test_a_restart_keeps_the_sessions_step_rates_for_the_new_runs_eta():
    b = ThreadWorkerBridge(make_fake_engine, {"n": 16})
    b.start()
    try:
        assert b.wait_until(lambda s: b.rates.median("stylize") is not None or s.error, 30), b.state.error
        b.restart({"n": 16})
        assert b.rates.median("stylize") is not None and b.rates.phase == (None, 0)  # kept; a new run's phases
        assert b.state.step_times.counts == {}  # the new run counts its own
    finally:
        b.quit(timeout=5)


SPAWNED_HELPER_THREADS = """
import sys
sys.path.insert(0, {root!r})
import torch
from app.child_process import single_compute_thread
single_compute_thread()
torch.ones(100_000).sum()
import numba
numba.get_num_threads()  # the engine's first parallel kernel launches numba's pool (1 thread in a helper)
print(torch.get_num_threads(), numba.get_num_threads())
"""


def test_a_spawned_helpers_torch_threads_hold_past_numbas_launch():
    # numba's OpenMP pool of 1, launched after torch's count was set, used to reset torch's count to 1
    import subprocess
    import sys
    from pathlib import Path

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"} | {"GSTYLE_WORKER_THREADS": "2"}
    code = SPAWNED_HELPER_THREADS.format(root=str(Path(__file__).resolve().parents[1]))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env,
                         check=True)
    assert out.stdout.split()[-2:] == ["2", "1"], out.stdout + out.stderr


def test_after_the_gpu_failed_the_run_goes_on_on_the_cpu_from_its_last_finished_step(monkeypatch):
    """A stand-in GPU runs out of memory at a stylize step: the error is one line and the worker offers the CPU;
    move_to("cpu") builds the engine on the CPU with the failed engine's state (the colours its last finished step
    left, bit for bit) and runs to the end."""
    from fakes import BUILT, stand_in_gpu_stylizer

    from gstyle_core.engine.stylizer import Stylizer

    loaded = []
    load = Stylizer.load_state_dict

    def recording_load(engine, state):
        load(engine, state)
        loaded.append((engine, engine.c_s.clone(), engine.global_step))

    monkeypatch.setattr(Stylizer, "load_state_dict", recording_load)
    BUILT.clear()
    b = ThreadWorkerBridge(stand_in_gpu_stylizer, {"n": 80})
    b.start()
    try:
        assert b.wait_until(lambda s: s.error is not None or s.done, 120)
        assert b.state.device_failed and "ran out of memory in stylize" in b.state.error, b.state.error
        assert "\n" not in b.state.error and b.state.paused
        failed, last = BUILT[-1], b.state.last_report["step"]
        assert failed.global_step == last and failed.phase == "stylize"  # the failed step was not counted
        colours = failed.c_s.clone()
        history = len(b.state.loss_history)
        b.set_params(lambda_nnfm=7.0)  # a slider moved after the failure comes over too
        assert b.wait_until(lambda s: s.params.get("lambda_nnfm") == 7.0, 10)
        b.move_to(dict(b.config), "cpu")
        assert not b.state.device_failed and b.state.error is None
        assert b.wait_until(lambda s: s.done or s.error, 120), "the run did not end on the CPU"
        assert b.state.error is None, b.state.error
        engine, at_load, step = loaded[-1]
        assert engine is BUILT[-1] is not failed and engine.settings.device == "cpu"
        assert engine.settings.weights.nnfm == 7.0 and b.state.params["lambda_nnfm"] == 7.0
        assert step == last == b.state.resumed["step"] and torch.equal(at_load, colours)
        assert b.state.last_report["step"] > last and len(b.state.loss_history) > history  # it went on, kept
    finally:
        assert b.quit(timeout=30)


def test_a_paused_run_moved_to_another_device_stays_paused_where_it_was():
    from fakes import keep_small_stylizer

    b = ThreadWorkerBridge(keep_small_stylizer, {"n": 80})
    b.start()
    try:
        # (a stylize step reported: the last report alone may be past the phase, its steps drained in one poll)
        assert b.wait_until(lambda s: s.step_times.counts.get("stylize") or s.error, 120)
        b.pause()
        assert b.wait_until(lambda s: s.paused, 30)
        step = b.state.last_report["step"]
        b.move_to(dict(b.config), "cpu")
        assert b.wait_until(lambda s: s.resumed is not None or s.error, 60) and b.state.error is None
        reports = b.state.reports_received
        time.sleep(0.5)
        b.poll()
        assert b.state.paused and b.state.reports_received == reports and b.state.resumed["step"] == step
        assert b.state.device == "cpu" and b.state.device_name == "CPU"
    finally:
        assert b.quit(timeout=30)


def test_a_gpu_that_was_never_there_leaves_the_cpu_to_start_afresh():
    """The engine could not be built on the device asked for (none there): the CPU is offered and starts afresh."""
    b = ThreadWorkerBridge(unavailable_gpu_engine, {"n": 16})
    b.start()
    try:
        assert b.wait_until(lambda s: s.error is not None, 30)
        assert b.state.device_failed and "sees no CUDA device" in b.state.error
        b.move_to(dict(b.config), "cpu")
        assert b.wait_until(lambda s: s.snapshots_received >= 2 or s.error, 30), b.state.error
        assert b.state.error is None and b.state.resumed is None
    finally:
        assert b.quit(timeout=30)


def unavailable_gpu_engine(device=None, **config):
    """A ``FakeEngine`` that cannot be built on any device but "cpu" (as on a machine with no CUDA device)."""
    from gstyle_core.device import DeviceUnavailable

    if device != "cpu":
        raise DeviceUnavailable("--device cuda: torch sees no CUDA device (a stand-in)")
    return make_fake_engine(**config)
