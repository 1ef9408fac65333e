"""The engine worker's side: a spawned process (or, in thread mode, a thread of the UI process) that owns the
engine, executes the UI's commands and sends reports and snapshots back (``app/worker.py`` is the UI's side).

The engine protocol (``gstyle_core.engine.Stylizer`` implements it): ``engine = factory(**config)`` built in the
worker, ``engine.step()`` -> report (.phase .step .total_steps .losses .seconds .gaussians .colours_changed
.geometry_changed .done), ``engine.set_params(**kw)``, ``engine.snapshot()`` -> dict of numpy arrays,
``engine.state_dict()`` / ``load_state_dict``.

Snapshots carry colours after every step and the geometry only when ``geometry_version`` changed. A credit
semaphore bounds the snapshots in flight, so a fast engine never floods a slow UI: when no credit is free the
snapshot is sent later (the newest one). Errors are sent as one line of text (where the run stopped, what failed,
and for a bug the crash log with its traceback: ``gstyle_core/crash.py``) and the worker stays alive so ``restart``
can rebuild the engine, or ``continue`` go on from the last finished step. Checkpoints, kept runs, resumes and
moves to another device are in ``app/engine_saves.py``.
"""

from __future__ import annotations

import copy
import dataclasses
import multiprocessing as mp
import queue
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gstyle_core.assets import DEMO_SCENE
from gstyle_core.crash import log_crash, what_failed
from gstyle_core.device import available_devices, is_device_failure
from gstyle_core.engine.controls import painting_controls
from gstyle_core.engine.run_crash import all_controls, controls_in_force, where_the_run_is
from gstyle_core.errors import GStyleError, one_line_error

from .child_process import lower_priority, single_compute_thread, worker_nice
from .engine_saves import RunSaves
from .export import export_engine
from .snapshot import GeometrySends

IDLE_POLL_SECONDS = 0.05
SUMMARY_DELAY_SECONDS = 0.5  # a finished run whose colours a control changed is measured again once they rest this long
REPORT_FIELDS = ("phase", "step", "total_steps", "losses", "seconds", "gaussians", "colours_changed",
                 "geometry_changed", "done", "message", "width")
PAINTING_PARAMS = painting_controls()  # engine params that belong to the config's paintings, not carried to a new one


def report_to_dict(report: Any) -> dict[str, Any]:
    """Plain dict of a step report (dataclass or any object with the protocol's attributes)."""
    if dataclasses.is_dataclass(report):
        out = dataclasses.asdict(report)
    else:
        out = {k: getattr(report, k) for k in REPORT_FIELDS if hasattr(report, k)}
    out["losses"] = {str(k): float(v) for k, v in dict(out.get("losses") or {}).items()}
    return out


class EngineHost:
    """Lives in the child: owns the engine, executes commands, sends reports and snapshots."""

    def __init__(self, factory: Callable[..., Any], config: dict[str, Any], events: Any, credits: Any,
                 checkpoint_path: str | None) -> None:
        self.factory, self.config, self.events, self.credits = factory, config, events, credits
        self.checkpoint_path = checkpoint_path
        self.fingerprint: dict[str, str] = {}  # what the engine was built from (checked before resuming)
        self.engine: Any = None
        self.paused, self.done, self.failed = False, False, False
        self.saves = RunSaves(self)  # checkpoints, kept runs, resumes, hand-overs (app/engine_saves.py)
        self.geometry_sends = GeometrySends()
        self.snapshot_pending, self.params_taken = False, 0  # params_taken: set_params commands (the UI's sliders)
        self.last_report: dict[str, Any] | None = None
        self.params: dict[str, float] = {}
        self.build_params: dict[str, float] = {}  # the params the engine was built with (its fingerprint's settings)
        self.level_weights: dict[str, tuple[float, float]] = {}  # weights Refine's level set: (before, the level's)
        self.sent_decisions: dict[str, Any] | None = None
        self.sent_setup_note = ""
        self.in_thread = False  # a worker thread of the UI process (ThreadWorkerBridge), not a spawned process
        self.summary_due: float | None = None  # when a finished run's summary is measured again (monotonic seconds)

    def send(self, kind: str, payload: Any = None) -> None:
        self.events.put((kind, payload))

    def fail(self, exc: BaseException, during: str) -> None:
        """Stop stepping at ``exc``: the UI gets one line (``failure_line``) and keeps its last good snapshot. After
        the GPU's failure it offers the CPU (``device_failed``); after another, with an engine, Continue from the last
        finished step (``failed``' ``continue_from``: a step that failed keeps none of its work)."""
        self.failed = True
        self.paused = True
        self.snapshot_pending = False  # never ship the state of a failed step: the UI keeps the last good one
        self.send("error", self.failure_line(exc, during))
        device = self.config.get("device") != "cpu" and is_device_failure(exc)
        if device:  # the UI offers the CPU (move_to)
            self.send("device_failed", None)
        self.send("failed", {"continue_from": None if device or self.engine is None else self.steps_done()})

    def failure_line(self, exc: BaseException, during: str) -> str:
        """``DURING WHERE: Type: first line``: where the run is (its phase and step) and what failed, with the crash
        log of a bug (``worded``)."""
        where = where_the_run_is(self.engine) if self.engine is not None else ""
        rep = self.last_report
        if not where and rep:  # an engine that cannot tell: its last report
            where = f"in phase {rep.get('phase')} at step {int(rep.get('step', 0)) + 1}"
        return self.worded(exc, f"{during}{f' {where}' if where else ''}: {what_failed(exc)}")

    def worded(self, exc: BaseException, line: str) -> str:
        """``line`` about ``exc``; for a bug (not a ``GStyleError`` or an ``OSError``, which are worded for the
        artist already) with the crash log that has its traceback (``gstyle_core/crash.py``)."""
        if isinstance(exc, (GStyleError, OSError)):
            return line
        details = [f"studio worker: {line}", f"engine config: {self.config}", f"params: {self.params}"]
        if self.engine is not None:
            details += [controls_in_force(self.engine), all_controls(self.engine)]
        return f"{line}; {log_crash(exc, 'studio', details)}"

    def steps_done(self) -> int:
        """The steps the run has done: the engine's count, else its last report's."""
        done = getattr(self.engine, "global_step", None)
        if done is None and self.last_report is not None:
            done = self.last_report.get("step")
        return int(done or 0)

    def build(self, config: dict[str, Any] | None = None, resume_from: str | None = None) -> None:
        """Build the engine from ``config`` (default: the current one); ``resume_from``: a checkpoint to continue
        (a result's run is rebuilt from the inputs kept with it, ``RunSaves.saved_inputs``)."""
        if config is not None:
            self.config = config
            for key in PAINTING_PARAMS:  # a new config's paintings come with their own mix (its style_weights)
                self.params.pop(key, None)
        self.engine, self.done, self.failed, self.summary_due = None, False, False, None
        self.geometry_sends = GeometrySends()
        self.sent_decisions, self.sent_setup_note = None, ""
        saved = self.saves.read(resume_from) if resume_from else None
        if saved is not None:
            self.params, self.level_weights, self.config = self.saves.saved_inputs(saved[1], self.params, self.config)
        else:  # a run from its inputs has no finer levels yet: the weights a level set go back
            self.drop_level_weights()
        try:
            from gstyle_core.engine.checkpoint import saved_capacity

            kept = saved_capacity(saved[0]) if saved is not None else None  # the saved run's cap, not today's
            self.engine = self.factory(**self.config, **({"capacity": kept} if kept else {}))
            single_compute_thread(self.in_thread)
            self.build_params = dict(self.params)
            if self.params:
                self.engine.set_params(**self.params)
            current = getattr(self.engine, "current_params", None)
            if current is not None:  # the resolved settings (e.g. λ_NNFM 10 for a 360° scene) reach the sliders
                self.params.update(current())
            from gstyle_core.engine.checkpoint import engine_fingerprint

            self.fingerprint = engine_fingerprint(self.engine)
        except Exception as exc:  # noqa: BLE001 - any engine error is reported, never fatal
            self.fail(exc, "building the engine")
            return
        choice = getattr(self.engine, "device_choice", None)
        self.send("ready", {"paused": self.paused, "device": getattr(choice, "kind", None),
                            "device_name": getattr(choice, "name", None), "devices": available_devices()})
        if saved is not None:
            self.saves.load_checkpoint(resume_from, saved)
        self.send_plans()  # after a loaded run (its levels, the width it is at): what Refine and the ETA go on from
        if self.params:
            self.send("params", dict(self.params))
        self.send_decisions()
        self.snapshot_pending = True
        self.flush_snapshot()

    def step(self) -> None:
        self.send_setup_note()  # before a step that builds gsplat's module (minutes): the UI says so meanwhile
        try:
            report = report_to_dict(self.engine.step())
        except Exception as exc:  # noqa: BLE001
            self.fail(exc, "the run stopped")
            return
        self.last_report = report
        self.done = bool(report.get("done"))
        self.send("report", report)
        self.send_setup_note()
        self.send_decisions()
        self.snapshot_pending = True
        self.flush_snapshot()
        self.saves.autosave()
        if self.done:
            self.send_summary()

    def send_setup_note(self) -> None:
        """The engine's ``setup_note`` (a one-off setup about to take minutes, or what it took), when it changed."""
        try:
            note = str(getattr(self.engine, "setup_note", "") or "")
        except Exception as exc:  # noqa: BLE001 - a note that cannot be worded is no reason to stop the run
            note = f"rasterizer setup: {one_line_error(exc)}"
        if note != self.sent_setup_note:
            self.sent_setup_note = note
            self.send("setup_note", note)

    def send_plans(self) -> None:
        """Every preset's steps here (the panel prices them), the preset run, its levels and the width it is at."""
        plans = getattr(self.engine, "preset_plans", None)
        if plans is None:
            return
        try:
            self.send("plans", {"plans": plans(), "run": self.engine.run_plan(), "preset": self.engine.settings.preset,
                                "working_width": int(self.engine.settings.working_width),
                                "levels": list(self.engine.levels), "next_width": self.engine.next_level_width(),
                                "width": getattr(self.engine, "current_width", None)})
        except Exception as exc:  # noqa: BLE001 - the estimates are a courtesy: say why they are missing
            self.send("error", f"estimating the presets: {one_line_error(exc)}")

    def send_summary(self) -> None:
        """The finished run's summary (``gstyle_core.engine.run_figures.result_summary``: its speckle at a display's
        size), for engines that have one."""
        if not hasattr(self.engine, "input_scene"):
            return
        try:
            from gstyle_core.engine.run_figures import result_summary

            self.send("summary", result_summary(self.engine))
        except Exception as exc:  # noqa: BLE001
            self.send("summary", {"line": self.worded(exc, f"no summary: {what_failed(exc)}")})

    def refine(self) -> None:
        """Carry the run on at its next finer level (``engine.refine()``), from its colours as they are."""
        if self.engine is None or not hasattr(self.engine, "refine"):
            self.send("error", "refine: this engine has no finer levels")
            return
        if self.failed:  # it would wait for steps that never come
            self.send("refine_refused", "refine: the run stopped at an error; Continue or Restart it first")
            return
        try:
            width = self.engine.refine()
        except ValueError as exc:  # at the largest width: one line, the run stays as it is
            self.send("refine_refused", one_line_error(exc))
            return
        self.done = False
        self.send("refining", width)
        current = getattr(self.engine, "current_params", None)
        moved = {k: v for k, v in (current() if current is not None else {}).items() if self.params.get(k) != v}
        if moved:  # the level changed weights (a 360° preview's first level): the sliders show them while it runs
            for name, value in moved.items():
                before = self.level_weights.get(name, (self.params.get(name), value))[0]
                if before is not None:
                    self.level_weights[name] = (before, value)
            self.params.update(moved)
            self.send("params", dict(self.params))
        self.send_plans()
        self.send_decisions()

    def drop_level_weights(self) -> None:
        """A run started again has none of Refine's levels: each weight a level set goes back to its value before
        the refine, unless the artist moved it since (then the artist's value stays)."""
        for name, (before, level) in self.level_weights.items():
            if self.params.get(name) == level:
                self.params[name] = before
        self.level_weights = {}

    def send_decisions(self) -> None:
        """Forward the engine's ``decisions`` dict (if it has one) whenever it changed."""
        decisions = getattr(self.engine, "decisions", None)
        if isinstance(decisions, dict) and decisions != self.sent_decisions:
            self.sent_decisions = copy.deepcopy(decisions)
            self.send("decisions", copy.deepcopy(decisions))

    def flush_snapshot(self, force: bool = False) -> None:
        """Send the engine's current snapshot if one is owed and a credit is free (``force``: even without)."""
        if not self.snapshot_pending or self.engine is None:
            return
        credit = bool(self.credits.acquire(False))  # positional: mp and threading semaphores both take it
        if not credit and not force:
            return
        try:
            snap = dict(self.engine.snapshot())
        except Exception as exc:  # noqa: BLE001
            if credit:
                self.credits.release()
            self.fail(exc, "snapshot")
            return
        snap = self.geometry_sends.shape(snap, force or self.done or self.paused)
        if snap is None:  # colours of a count whose geometry is held back: they go with it
            if credit:
                self.credits.release()
            return
        self.snapshot_pending = False
        self.send("snapshot", (credit, snap))

    def handle(self, command: str, arg: Any) -> bool:
        """Execute one command; False means quit."""
        if command == "pause":
            self.paused = True
            self.flush_snapshot(force=True)  # the last step's colours arrive before the acknowledgement
            self.send("paused", True)
        elif command == "resume":
            self.paused = self.failed  # after a failure nothing steps until Continue, a move or a restart
            self.send("paused", self.paused)
        elif command == "step":
            if self.engine is not None and not (self.done or self.failed):  # after a failure: Continue, not a retry
                self.step()
        elif command in ("restart", "restart_from"):
            self.saves.drop_handover()  # a restart starts from its inputs: no run to move on from
            self.paused = False
            self.send("paused", False)
            self.build(*(arg if command == "restart_from" else (arg,)))
        elif command in ("move_to", "continue"):  # continue: after a failure, on the device it is on
            if self.failed or self.engine is None:  # after a failure the run goes on; a paused one stays paused
                self.paused = False
            self.send("paused", self.paused)
            self.saves.move_to(arg if command == "move_to" else self.config)
        elif command == "checkpoint_path":
            self.checkpoint_path = arg
        elif command == "set_params":
            self.set_params(arg)
        elif command == "export":
            self.export(arg)
        elif command == "refine":
            self.refine()
        elif command == "quit":
            self.saves.checkpoint()
            self.send("bye", None)
            return False
        return True

    def set_params(self, params: dict[str, float]) -> None:
        """Controls from the next step, echoed with the count taken ("params_taken": ``app/artist_params.py``)."""
        self.params.update(params)
        self.params_taken += 1
        colours = getattr(self.engine, "colour_version", None)
        try:
            if self.engine is not None:
                self.engine.set_params(**params)
        except Exception as exc:  # noqa: BLE001
            self.fail(exc, "set_params")
            return
        self.send("params", dict(self.params))
        self.send("params_taken", self.params_taken)
        if getattr(self.engine, "colour_version", None) != colours:  # e.g. keep colours restored the hues at once,
            self.snapshot_pending = True  # the palette match blended a finished run again: shown without waiting for
            self.flush_snapshot(force=True)  # a step, with the geometry its colours belong to (not held back)
            if self.done:  # its summary describes the colours shown (measured once a slider's drag rests)
                self.summary_due = time.monotonic() + SUMMARY_DELAY_SECONDS

    def send_due_summary(self) -> None:
        """The finished run's summary measured again (``send_summary``) when a control changed its colours and they
        have rested ``SUMMARY_DELAY_SECONDS`` since (a drag's every frame would each cost a measure)."""
        if self.summary_due is None or time.monotonic() < self.summary_due:
            return
        self.summary_due = None
        if self.done and self.engine is not None:
            self.send_summary()

    def export(self, path: str) -> None:
        if self.engine is None:
            self.send("error", "export: no engine is running")
            return
        try:
            written = export_engine(self.engine, Path(path), self.last_report, self.params, self.config.get("style"),
                                    self.config.get("scene") or str(DEMO_SCENE))
        except Exception as exc:  # noqa: BLE001 - one line in the panel; the run goes on, nothing was written
            self.send("export_failed", self.worded(exc, f"export: {what_failed(exc)}"))
            return
        self.saves.keep_run(written)
        self.send("exported", written)

    def should_step(self) -> bool:
        return self.engine is not None and not (self.paused or self.done or self.failed)


def worker_main(factory: Callable[..., Any], config: dict[str, Any], commands: Any, events: Any, credits: Any,
                checkpoint_path: str | None, start_paused: bool, resume_from: str | None = None,
                in_thread: bool = False) -> None:
    """Entry point of the spawned process (or, with ``in_thread``, of the UI process's worker thread: no nice,
    which would apply to the whole process). A bug that stops the loop itself is one line to the UI, its traceback
    in a crash log (the UI then sees the worker gone)."""
    single_compute_thread(in_thread)
    if not in_thread:
        lower_priority(worker_nice())
    host = EngineHost(factory, config, events, credits, checkpoint_path)
    host.in_thread = in_thread
    host.paused = start_paused
    try:
        host.build(resume_from=resume_from)
        serve(host, commands, None if in_thread else mp.parent_process())
    except Exception as exc:  # noqa: BLE001 - the worker's own bug: said, logged, and the worker ends
        host.send("error", host.worded(exc, f"the engine worker stopped: {what_failed(exc)}"))


def serve(host: EngineHost, commands: Any, parent: Any) -> None:
    """The worker's loop: every pending command first, then a snapshot owed and a step, until "quit" (or the UI's
    process, ``parent``, is gone)."""
    running = True
    while running:
        try:
            timeout = 0 if host.should_step() else IDLE_POLL_SECONDS
            command, arg = commands.get(timeout=timeout) if timeout else commands.get_nowait()
            running = host.handle(command, arg)
            continue  # drain all pending commands before the next step
        except queue.Empty:
            pass
        if parent is not None and not parent.is_alive():
            break
        host.flush_snapshot()
        host.send_due_summary()
        if host.should_step():
            host.step()
