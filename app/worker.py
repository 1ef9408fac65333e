"""Worker bridge, the UI's side: start the engine worker (``app/engine_host.py``) in a spawned process, command it
and poll its messages through queues.

Transport: pickled numpy through ``multiprocessing`` queues, fast enough for colour updates of 1.2 M Gaussians a
step (``bench/studio_rate.py`` counts the snapshots arriving a second, ``bench/ui.py`` the frames beside them). A credit
semaphore bounds the snapshots in flight (``SNAPSHOT_CREDITS``). The worker runs with one compute thread and a raised
nice value, and ignores Ctrl+C: the studio asks it to save and stop (``quit``).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gstyle_core.engine.plan import MachineRates, StepTimes

from .artist_params import ArtistParams
from .child_process import exit_words, interrupts_ignored
from .engine_host import worker_main

SNAPSHOT_CREDITS = 2

STEP_KEY = "step"  # in each ``WorkerState.loss_history`` entry: the engine step its losses were recorded at


# ====================================================================== messages (child -> UI)
@dataclass
class WorkerState:
    """What the UI knows about the worker, updated by ``WorkerBridge.poll``."""

    alive: bool = False
    ready: bool = False  # engine built
    paused: bool = False
    done: bool = False
    error: str | None = None
    went_on_after: str | None = None  # an error a later step made stale (shown once: ``take_went_on_after``)
    last_report: dict[str, Any] | None = None
    loss_history: list[dict[str, float]] = field(default_factory=list)
    snapshot: dict[str, Any] = field(default_factory=dict)  # merged: geometry kept until a new one arrives
    snapshots_received: int = 0
    reports_received: int = 0
    step_seconds: float = 0.0  # sum of the reports' step times (for the ETA)
    geometry_received: int = 0
    gt_colours_received: int = 0  # snapshots that carried c_gt (only those with new geometry)
    params: dict[str, float] = field(default_factory=dict)  # the worker's (the panel's wait for ``artist``)
    artist: ArtistParams = field(default_factory=ArtistParams)  # the artist's changes the worker has not taken yet
    decisions: dict[str, Any] = field(default_factory=dict)  # the engine's "what this scene needs" decisions
    exported: list[str] = field(default_factory=list)
    export_failures: list[str] = field(default_factory=list)  # one line each ("export: cannot write ...")
    checkpoint: str | None = None
    autosaved: dict[str, Any] | None = None  # the worker's last own save: {"path", "step", "seconds"}
    resumed: dict[str, Any] | None = None  # {"checkpoint": path, "step": n} once a checkpoint was loaded
    started_at: float = 0.0
    plans: dict[str, Any] = field(default_factory=dict)  # every preset's steps, the preset run, its widths (plans)
    width: int = 0  # the width the run is at: the newest report's, or the plans' (a run loaded or refined) if newer
    step_times: StepTimes = field(default_factory=StepTimes)  # this run's steps of each kind (its ETA)
    summary: dict[str, Any] | None = None  # the finished run's summary (its speckle at a display's size)
    refine_note: str = ""  # why Refine was refused, or the level it started (while that level runs)
    refining: bool = False  # a Refine level runs (``refine_note`` says its width until the run is done)
    setup_note: str = ""  # the engine's one-off setup: a build under way (minutes) or how long it took
    device_failed: bool = False  # the GPU failed (no device, memory, rasterizer): the CPU can go on (``move_to``)
    device: str | None = None  # what the engine computes on ("cpu", "cuda", "mps"; None: no engine built yet)
    device_name: str = ""  # the same in words (the card)
    devices: tuple[str, ...] = ("cpu",)  # the devices the worker can compute on (``device.available_devices``)
    failed: bool = False  # an engine error stopped the run: nothing steps until Continue, a move or a restart
    continue_from: int | None = None  # after ``failed``: the last finished step, where Continue goes on (None: no
    # engine to go on from, or the GPU's failure, whose way on is the CPU)

    @property
    def stepping(self) -> bool:
        """True while the worker steps the engine: alive, built, and not paused, done or stopped by an error."""
        return self.alive and self.ready and not (self.paused or self.done or self.failed)

    def take_went_on_after(self) -> str | None:
        """The stale error (``went_on_after``) once: it is forgotten as it is read."""
        line, self.went_on_after = self.went_on_after, None
        return line


# ====================================================================== the UI side
class WorkerBridge:
    """Start, command and poll an engine running in a spawned process."""

    def __init__(self, factory: Callable[..., Any], config: dict[str, Any] | None = None, *,
                 checkpoint_path: str | os.PathLike | None = None, start_paused: bool = False,
                 resume_from: str | os.PathLike | None = None, rates: MachineRates | None = None) -> None:
        self.factory = factory
        self.rates = rates if rates is not None else MachineRates()  # every step's time goes there too (the studio's
        # session rates of this scene and device: the quality estimates); the studio may hand it another
        self.config = dict(config or {})
        self.checkpoint_path = str(checkpoint_path) if checkpoint_path else None
        self.resume_from = str(resume_from) if resume_from else None  # used by the next start()
        self.start_paused = start_paused
        self.state = WorkerState()
        self._mp = mp.get_context("spawn")
        self._process: Any = None
        self._commands: Any = None
        self._events: Any = None
        self._credits: Any = None

    # ----------------------------------------------------------------- lifecycle
    in_thread = False  # ThreadWorkerBridge: the same loop in a thread of this process

    def _runtime(self) -> Any:
        """Where queues, the credit semaphore and the runner come from (``Queue``, ``Semaphore``, ``Process``)."""
        return self._mp

    def start(self) -> None:
        """Start the worker (the engine is built inside it): a spawned process, or a thread in thread mode."""
        rt = self._runtime()
        self._commands, self._events = rt.Queue(), rt.Queue()
        self._credits = rt.Semaphore(SNAPSHOT_CREDITS)
        self._process = rt.Process(
            target=worker_main, name="gstyle-engine", daemon=True,
            args=(self.factory, self.config, self._commands, self._events, self._credits, self.checkpoint_path,
                  self.start_paused, self.resume_from), kwargs={"in_thread": self.in_thread})
        self.resume_from = None
        self.rates.new_run()
        with interrupts_ignored():
            self._process.start()
        self.state = WorkerState(alive=True, paused=self.start_paused, started_at=time.monotonic())

    @property
    def alive(self) -> bool:
        """True while the worker process runs."""
        return self._process is not None and self._process.is_alive()

    def quit(self, timeout: float = 10.0) -> bool:
        """Ask the worker to checkpoint and exit; terminate it (then kill it) if it does not within ``timeout``.

        Returns True when the worker exited by itself (a checkpoint was then written if it had an engine)."""
        if self._process is None:
            return True
        clean = True
        self._ask_to_quit(timeout)
        if self.alive:
            clean = False
            self._process.terminate()
            self._process.join(2.0)
            if self._process.is_alive():  # SIGTERM ignored or stuck: SIGKILL
                self._process.kill()
                self._process.join(2.0)
            self.state.error = f"the engine did not stop within {timeout:g} s and was killed; no checkpoint saved"
        self.state.alive = False
        self._process = None
        return clean

    def _ask_to_quit(self, timeout: float) -> None:
        """Send "quit" and keep polling (the worker's last messages) until it stops or ``timeout`` s pass."""
        if self.alive:
            self._send("quit")
            deadline = time.monotonic() + timeout
            while self.alive and time.monotonic() < deadline:
                self.poll()
                self._process.join(0.05)
        self.poll()

    # ----------------------------------------------------------------- commands
    def pause(self) -> None:
        """Stop stepping after the current step; ``state.paused`` turns True when the worker acknowledges."""
        self._send("pause")

    def resume(self) -> None:
        """Step continuously (``state.paused`` turns False when the worker acknowledges)."""
        self._send("resume")

    def toggle_pause(self) -> None:
        """Pause if running, resume if paused."""
        self.resume() if self.state.paused else self.pause()

    def step_once(self) -> None:
        """Run exactly one step (useful while paused)."""
        self._send("step")

    def restart(self, config: dict[str, Any] | None = None, resume_from: str | os.PathLike | None = None) -> None:
        """Rebuild the engine (with a new config if given), continuing from the checkpoint ``resume_from`` if
        given; respawns the process if it died."""
        if config is not None:
            self.config = dict(config)
        if not self.alive:
            self.resume_from = str(resume_from) if resume_from else None
            self.start()
            return
        self._forget_engine()
        self.state.loss_history.clear()
        self.state.reports_received, self.state.step_seconds, self.state.last_report = 0, 0.0, None
        self.state.step_times = StepTimes()  # (the runs before stay in ``rates``, which price the new one's ETA)
        self.rates.new_run()
        if resume_from:
            self._send("restart_from", (self.config, str(resume_from)))
        else:
            self._send("restart", self.config)

    def _forget_engine(self) -> None:
        """What the UI knew of the engine being replaced: its error, end, pause, device, decisions, resume and
        summary."""
        st = self.state
        st.error, st.done, st.paused, st.device_failed, st.device = None, False, False, False, None
        st.decisions, st.resumed, st.summary, st.refine_note, st.refining = {}, None, None, "", False
        st.failed, st.continue_from, st.width = False, None, 0

    def move_to(self, config: dict[str, Any], device: str) -> None:
        """Go on on ``device`` ("cpu" after the GPU failed, ``state.device_failed``): the worker builds the engine
        again there from ``config`` and goes on from where the run was (``EngineHost.move_to``; a paused run stays
        paused, a failed one goes on); the loss history stays, the step times start again (another device's
        differ). A worker that is gone starts afresh."""
        self.config = {**config, "device": device}
        if not self.alive:
            self.resume_from = None
            self.start()
            return
        self._forget_engine()
        self.state.step_times = StepTimes()
        self.rates.new_run()
        self._send("move_to", self.config)

    def continue_run(self) -> None:
        """After an engine error (``state.failed``): the worker builds the engine again on the device it is on and goes
        on from the run's last finished step (``state.continue_from``: the failed step kept none of its work); the
        loss history and the step times stay. A worker that is gone starts afresh."""
        if not self.alive:
            self.resume_from = None
            self.start()
            return
        self._forget_engine()
        self._send("continue")

    def set_checkpoint_path(self, path: str | os.PathLike | None) -> None:
        """Where the worker saves its checkpoint when it quits (e.g. after the scene or style changed)."""
        self.checkpoint_path = str(path) if path else None
        self._send("checkpoint_path", self.checkpoint_path)

    def set_params(self, **params: float) -> None:
        """Change engine parameters (the live controls of ``gstyle_core.engine.controls``: λ weights, strength,
        stroke size, keep colours, split rate, lr, style mix) from the next step on."""
        self.state.artist.sending(params)
        self._send("set_params", dict(params))

    def refine(self) -> None:
        """Carry the run on at its next finer level from the colours it has (no restart)."""
        self._send("refine")

    def export(self, path: str | os.PathLike) -> None:
        """Ask the worker to save the stylized scene (.ply, .spz, .compressed.ply or .sog; + .json summary) at
        ``path``."""
        self._send("export", str(path))

    def _send(self, command: str, arg: Any = None) -> None:
        if self.alive:
            self._commands.put((command, arg))
        else:
            self.state.error = self.state.error or "the engine process is not running; press Restart"

    # ----------------------------------------------------------------- events
    def poll(self, max_messages: int = 1000) -> list[tuple[str, Any]]:
        """Apply all pending worker messages to ``state``; returns them (oldest first) as (kind, payload).

        Kinds: ready, report (dict), snapshot ((credit_taken, dict)), error (str), paused (bool), params (dict),
        decisions (dict), exported (path), export_failed (one line), checkpoint (path), autosaved (dict: path, step,
        seconds), resumed (dict), plans (dict), summary (dict), refining (width), refine_refused (one line),
        setup_note (one line), device_failed (None: the GPU failed, ``move_to`` the CPU goes on), failed
        ({"continue_from": step or None}: an engine error stopped the run, ``continue_run`` goes on),
        params_taken (int: set_params commands taken), bye.
        """
        messages: list[tuple[str, Any]] = []
        if self._events is None:
            return messages
        for _ in range(max_messages):
            try:
                kind, payload = self._events.get_nowait()
            except (queue.Empty, OSError, ValueError):
                break
            messages.append((kind, payload))
            self._apply(kind, payload)
        self.state.alive = self.alive
        if self._process is not None and not self.state.alive and self.state.error is None and not any(
                k == "bye" for k, _ in messages):
            code = getattr(self._process, "exitcode", None)  # a thread (thread mode) has none
            if code not in (0, None):
                self.state.error = exit_words(code, str(self.state.decisions.get("capacity") or ""))
            elif code is None and not hasattr(self._process, "exitcode"):
                self.state.error = "the engine thread stopped unexpectedly (see the console)"
        return messages

    def _apply(self, kind: str, payload: Any) -> None:
        st = self.state
        if kind == "ready":
            st.ready, st.error, st.done, st.device_failed = True, None, False, False
            st.failed, st.continue_from = False, None
            st.device, st.device_name = payload.get("device"), str(payload.get("device_name") or "")
            st.devices = tuple(payload.get("devices") or ("cpu",))
        elif kind == "report":
            self._apply_report(payload)
        elif kind == "snapshot":
            credit, payload = payload
            if credit:
                self._credits.release()
            if "means" in payload:
                st.geometry_received += 1
            if "colors_gt" in payload:
                st.gt_colours_received += 1
            st.snapshot.update(payload)
            st.snapshots_received += 1
        elif kind == "error":  # one line (an engine failure comes with "failed"; other errors leave the run going)
            st.error = payload
        elif kind == "failed":  # the worker stopped stepping: it says so until Continue, a move or a restart
            st.failed, st.paused, st.continue_from = True, True, payload.get("continue_from")
            st.refine_note = ""
        elif kind == "paused":
            st.paused = bool(payload)
        elif kind == "params":
            st.params = dict(payload)
        elif kind == "params_taken":  # the set_params commands taken (after the "params" echo of the last one)
            st.artist.took(int(payload), st.snapshots_received)
        elif kind == "decisions":
            st.decisions = dict(payload)
        elif kind == "exported":
            st.exported.append(payload)
        elif kind == "export_failed":  # one line for the panel; the engine goes on (not an engine error)
            st.export_failures.append(payload)
        elif kind in ("checkpoint", "autosaved"):  # a save at quit (its path), or on its own while stepping
            st.checkpoint = payload if kind == "checkpoint" else payload["path"]
            st.autosaved = payload if kind == "autosaved" else st.autosaved
        elif kind == "resumed":
            st.resumed = dict(payload)
        elif kind == "plans":
            st.plans, st.width = dict(payload), int(payload.get("width") or st.width)
        elif kind == "summary":
            st.summary = dict(payload)
        elif kind == "refining":
            st.done, st.summary, st.refining = False, None, True
            st.refine_note = f"refining at {payload} px"
        elif kind == "refine_refused":
            st.refine_note = str(payload)
        elif kind == "setup_note":
            st.setup_note = str(payload)
        elif kind == "device_failed":
            st.device_failed = True

    def _apply_report(self, report: dict[str, Any]) -> None:
        """A step succeeded: its report, step time and losses; an error before it is stale now (``went_on_after``),
        and a Refine level's note ends with the run."""
        st = self.state
        st.last_report, st.width = report, int(report.get("width") or st.width)
        st.reports_received += 1
        st.step_times.add(report)
        self.rates.add(report)
        st.step_seconds += float(report.get("seconds") or 0.0)
        st.done = bool(report.get("done"))
        if st.error is not None:
            st.went_on_after, st.error, st.device_failed = st.error, None, False
        if st.done and st.refining:
            st.refining, st.refine_note = False, ""
        losses = dict(report.get("losses") or {})
        if losses:  # each with the step it was recorded at (the plot's x axis)
            st.loss_history.append({STEP_KEY: float(report.get("step", len(st.loss_history))), **losses})

    def wait_until(self, predicate: Callable[[WorkerState], bool], timeout: float = 30.0) -> bool:
        """Poll until ``predicate(state)`` holds (True) or ``timeout`` seconds pass (False). For tests and CLI."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.poll()
            if predicate(self.state):
                return True
            time.sleep(0.01)
        self.poll()
        return predicate(self.state)


class ThreadWorkerBridge(WorkerBridge):
    """The same engine loop in a thread of the UI process instead of a spawned process (same protocol, queues
    without pickling). Kept to measure both ways (``bench/ui.py --worker thread``); the studio uses the process:
    the engine's Python work holds the GIL and competes with the UI thread (README, "The studio")."""

    in_thread = True

    def _runtime(self) -> Any:
        import queue as queue_module
        import threading
        from types import SimpleNamespace

        return SimpleNamespace(Queue=queue_module.Queue, Semaphore=threading.Semaphore, Process=threading.Thread)

    def quit(self, timeout: float = 10.0) -> bool:
        """Ask the worker thread to checkpoint and stop; a thread cannot be killed, so one that does not stop
        within ``timeout`` is left behind (daemon) and reported."""
        if self._process is None:
            return True
        self._ask_to_quit(timeout)
        clean = not self.alive
        if not clean:
            self.state.error = f"the engine thread did not stop within {timeout:g} s"
        self.state.alive = False
        self._process = None
        return clean
