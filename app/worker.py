"""Worker bridge: run a stylization engine in a spawned process and talk to it through queues.

The engine protocol (``gstyle_core.pipeline.Stylizer`` implements it): ``engine = factory(**config)`` built in the
child, ``engine.step()`` -> report (.phase .step .total_steps .losses .seconds .gaussians .colours_changed
.geometry_changed .done), ``engine.set_params(**kw)``, ``engine.snapshot()`` -> dict of numpy arrays,
``engine.state_dict()`` / ``load_state_dict``.

Transport: pickled numpy through ``multiprocessing`` queues (measured by ``bench/bench_worker_transfer.py``:
fast enough for colour updates of 100k+ Gaussians, see the report). Snapshots carry colours after every step and
the geometry only when ``geometry_version`` changed. A credit semaphore bounds the snapshots in flight, so a
fast engine never floods a slow UI: when no credit is free the snapshot is sent later (the newest one).
The child runs with ``torch.set_num_threads(1)`` and a raised nice value; errors are sent as one line of text
and the child stays alive so ``restart`` can rebuild the engine.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import multiprocessing as mp
import os
import queue
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gstyle_core.pipeline.controls import painting_controls

GEOMETRY_FIELDS = ("means", "log_scales", "quats", "opacity_logits")
# Sent only with a new geometry version: c_gt changes only when the geometry is refitted (the UI reads it then).
FOLLOW_GEOMETRY = (*GEOMETRY_FIELDS, "colors_gt")
SNAPSHOT_CREDITS = 2
IDLE_POLL_SECONDS = 0.05
REPORT_FIELDS = ("phase", "step", "total_steps", "losses", "seconds", "gaussians", "colours_changed",
                 "geometry_changed", "done", "message")


# ====================================================================== messages (child -> UI)
@dataclass
class WorkerState:
    """What the UI knows about the worker, updated by ``WorkerBridge.poll``."""

    alive: bool = False
    ready: bool = False  # engine built
    paused: bool = False
    done: bool = False
    error: str | None = None
    last_report: dict[str, Any] | None = None
    loss_history: list[dict[str, float]] = field(default_factory=list)
    snapshot: dict[str, Any] = field(default_factory=dict)  # merged: geometry kept until a new one arrives
    snapshots_received: int = 0
    reports_received: int = 0
    step_seconds: float = 0.0  # sum of the reports' step times (for the ETA)
    geometry_received: int = 0
    gt_colours_received: int = 0  # snapshots that carried c_gt (only those with new geometry)
    params: dict[str, float] = field(default_factory=dict)
    decisions: dict[str, Any] = field(default_factory=dict)  # the engine's "what this scene needs" decisions
    exported: list[str] = field(default_factory=list)
    checkpoint: str | None = None
    resumed: dict[str, Any] | None = None  # {"checkpoint": path, "step": n} once a checkpoint was loaded
    started_at: float = 0.0


def report_to_dict(report: Any) -> dict[str, Any]:
    """Plain dict of a step report (dataclass or any object with the protocol's attributes)."""
    if dataclasses.is_dataclass(report):
        out = dataclasses.asdict(report)
    else:
        out = {k: getattr(report, k) for k in REPORT_FIELDS if hasattr(report, k)}
    out["losses"] = {str(k): float(v) for k, v in dict(out.get("losses") or {}).items()}
    return out


def one_line_error(exc: BaseException) -> str:
    """``Type: message`` on one line (the full traceback goes to the worker's stderr)."""
    text = " ".join(str(exc).split()) or "(no message)"
    return f"{type(exc).__name__}: {text}"


# ====================================================================== the child process
class _EngineHost:
    """Lives in the child: owns the engine, executes commands, sends reports and snapshots."""

    def __init__(self, factory: Callable[..., Any], config: dict[str, Any], events: Any, credits: Any,
                 checkpoint_path: str | None) -> None:
        self.factory, self.config, self.events, self.credits = factory, config, events, credits
        self.checkpoint_path = checkpoint_path
        self.fingerprint: dict[str, str] = {}  # what the engine was built from (checked before resuming)
        self.engine: Any = None
        self.paused = False
        self.done = False
        self.failed = False
        self.sent_geometry_version: Any = object()
        self.snapshot_pending = False
        self.last_report: dict[str, Any] | None = None
        self.params: dict[str, float] = {}
        self.sent_decisions: dict[str, Any] | None = None
        self.in_thread = False  # a worker thread of the UI process (ThreadWorkerBridge), not a spawned process

    def send(self, kind: str, payload: Any = None) -> None:
        self.events.put((kind, payload))

    def fail(self, exc: BaseException, during: str) -> None:
        traceback.print_exc()
        self.failed = True
        self.paused = True
        self.snapshot_pending = False  # never ship the state of a failed step: the UI keeps the last good one
        self.send("error", f"{during}: {one_line_error(exc)}")

    def build(self, config: dict[str, Any] | None = None, resume_from: str | None = None) -> None:
        if config is not None:
            self.config = config
            for key in PAINTING_PARAMS:  # a new config's paintings come with their own mix (its style_weights)
                self.params.pop(key, None)
        self.engine, self.done, self.failed = None, False, False
        self.sent_geometry_version = object()
        self.sent_decisions = None
        try:
            self.engine = self.factory(**self.config)
            _single_torch_thread(self.in_thread)
            if self.params:
                self.engine.set_params(**self.params)
            current = getattr(self.engine, "current_params", None)
            if current is not None:  # the resolved settings (e.g. λ_NNFM 10 for a 360° scene) reach the sliders
                self.params.update(current())
            from gstyle_core.pipeline.checkpoint import engine_fingerprint

            self.fingerprint = engine_fingerprint(self.engine)
        except Exception as exc:  # noqa: BLE001 - any engine error is reported, never fatal
            self.fail(exc, "building the engine")
            return
        self.send("ready", {"paused": self.paused})
        if resume_from:
            self.load_checkpoint(resume_from)
        if self.params:
            self.send("params", dict(self.params))
        self.send_decisions()
        self.snapshot_pending = True
        self.flush_snapshot()

    def step(self) -> None:
        try:
            report = report_to_dict(self.engine.step())
        except Exception as exc:  # noqa: BLE001
            self.fail(exc, "step")
            return
        self.last_report = report
        self.done = bool(report.get("done"))
        self.send("report", report)
        self.send_decisions()
        self.snapshot_pending = True
        self.flush_snapshot()

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
        if snap.get("geometry_version") == self.sent_geometry_version:
            for key in FOLLOW_GEOMETRY:
                snap.pop(key, None)
        else:
            self.sent_geometry_version = snap.get("geometry_version")
        self.snapshot_pending = False
        self.send("snapshot", (credit, snap))

    def handle(self, command: str, arg: Any) -> bool:
        """Execute one command; False means quit."""
        if command == "pause":
            self.paused = True
            self.flush_snapshot(force=True)  # the last step's colours arrive before the acknowledgement
            self.send("paused", True)
        elif command == "resume":
            self.paused = False
            self.send("paused", False)
        elif command == "step":
            if self.engine is not None and not self.done:
                self.step()
        elif command in ("restart", "restart_from"):
            self.paused = False
            self.send("paused", False)
            self.build(*(arg if command == "restart_from" else (arg,)))
        elif command == "checkpoint_path":
            self.checkpoint_path = arg
        elif command == "set_params":
            self.set_params(arg)
        elif command == "export":
            self.export(arg)
        elif command == "quit":
            self.checkpoint()
            self.send("bye", None)
            return False
        return True

    def set_params(self, params: dict[str, float]) -> None:
        self.params.update(params)
        if self.engine is None:
            self.send("params", dict(self.params))
            return
        colours = getattr(self.engine, "colour_version", None)
        try:
            self.engine.set_params(**params)
        except Exception as exc:  # noqa: BLE001
            self.fail(exc, "set_params")
            return
        self.send("params", dict(self.params))
        if getattr(self.engine, "colour_version", None) != colours:  # e.g. keep colours restored the hues at once:
            self.snapshot_pending = True  # shown without waiting for a step (paused, or done)
            self.flush_snapshot()

    def export(self, path: str) -> None:
        if self.engine is None:
            self.send("error", "export: no engine is running")
            return
        try:
            written = export_engine(self.engine, Path(path), self.last_report, self.params, self.config.get("style"))
        except Exception as exc:  # noqa: BLE001
            self.send("error", f"export: {one_line_error(exc)}")
            return
        self.send("exported", written)

    def checkpoint(self) -> None:
        """Save the engine's state, the fingerprint of its inputs and the slider values (cache folder)."""
        if self.engine is None or not self.checkpoint_path:
            return
        try:
            from gstyle_core.pipeline.checkpoint import save_checkpoint

            meta = {"kind": "studio", "scene": self.config.get("scene"), "style": self.config.get("style"),
                    "fingerprint": self.fingerprint, "params": dict(self.params)}
            save_checkpoint(self.checkpoint_path, self.engine.state_dict(), meta)
            self.send("checkpoint", str(self.checkpoint_path))
        except Exception as exc:  # noqa: BLE001
            self.send("error", f"checkpoint: {one_line_error(exc)}")

    def load_checkpoint(self, path: str) -> None:
        """Continue from a checkpoint made for the same inputs; otherwise say why in one line and start fresh."""
        try:
            from gstyle_core.pipeline.checkpoint import load_checkpoint

            state, meta = load_checkpoint(path, self.fingerprint)
            self.engine.load_state_dict(state)
        except Exception as exc:  # noqa: BLE001 - a bad checkpoint is reported; the fresh engine carries on
            traceback.print_exc()
            self.send("error", f"resume: {one_line_error(exc)}; starting afresh")
            return
        step = getattr(self.engine, "global_step", state.get("global_step", state.get("steps")))
        self.send("resumed", {"checkpoint": str(path), "step": step})
        if meta.get("params"):
            self.set_params(dict(meta["params"]))

    def should_step(self) -> bool:
        return self.engine is not None and not (self.paused or self.done or self.failed)


EXPORT_FORMATS = ("ply", "spz", "compressed-ply")  # what the studio exports (the web formats for web viewers)


def export_engine(engine: Any, path: Path, last_report: dict[str, Any] | None, params: dict[str, float],
                  style: str | list[str] | None = None) -> str:
    """Save the stylized scene as .ply, .spz or .compressed.ply (``gstyle_core.io.save_scene``) and a JSON summary
    beside it (``name.json``; ``style``: the engine's painting path(s), named there with their weights)."""
    from gstyle_core.atomic import atomic_write_text
    from gstyle_core.errors import GStyleError
    from gstyle_core.io import save_scene
    from gstyle_core.io.saver import format_of
    from gstyle_core.scene import GaussianScene, rgb_to_sh_dc

    if format_of(path) not in EXPORT_FORMATS:
        raise GStyleError(f"export path must end in .ply, .spz or .compressed.ply, got {path.name}")
    if hasattr(engine, "stylized_scene"):
        scene = engine.stylized_scene()
    else:
        snap = engine.snapshot()
        scene = GaussianScene(*(snap[k] for k in GEOMETRY_FIELDS), rgb_to_sh_dc(snap["colors"]))
    save_scene(scene, path)
    summary = {"scene": str(path), "gaussians": scene.count, "styles": style_entries(engine, style),
               "report": last_report, "params": params,
               "decisions": getattr(engine, "decisions", None),
               "settings": engine.settings.to_dict() if hasattr(getattr(engine, "settings", None), "to_dict")
               else None}
    atomic_write_text(summary_path(path), json.dumps(summary, indent=2, default=str))
    return str(path)


def summary_path(export: str | Path) -> Path:
    """The JSON summary written beside an export: ``name.json`` for ``name.ply``, ``.spz`` or ``.compressed.ply``."""
    from gstyle_core.io.saver import COMPRESSED_PLY_SUFFIX, format_of

    path = Path(export)
    stem = path.name[: -len(COMPRESSED_PLY_SUFFIX)] if format_of(path) == "compressed-ply" else path.stem
    return path.with_name(stem + ".json")


def style_entries(engine: Any, style: str | list[str] | None) -> list[dict[str, Any]]:
    """[{"path", "weight"}] for the engine's paintings (weights from its settings; equal when it has none)."""
    paths = [style] if isinstance(style, str) else list(style or [])
    weights = list(getattr(getattr(engine, "settings", None), "style_weights", ()) or [])
    if len(weights) != len(paths):
        weights = [1.0 / len(paths)] * len(paths) if paths else []
    return [{"path": str(p), "weight": round(float(w), 6)} for p, w in zip(paths, weights, strict=True)]


PAINTING_PARAMS = painting_controls()  # engine params that belong to the config's paintings, not carried to a new one
WORKER_NICE = 10  # default niceness increment of the worker process (env GSTYLE_WORKER_NICE overrides it)


def _lower_priority(increment: int = WORKER_NICE) -> None:
    """Nice the worker (+10 by default) so the UI thread wins the CPU."""
    try:
        if increment:
            os.nice(int(increment))
    except OSError:
        pass


def _single_torch_thread(in_thread: bool = False) -> None:
    """One compute thread in the worker: torch's (measured best on 2 cores, gl-stack.md §3) and numba's (the
    rasterizer's parallel loops). With two numba threads the worker kept 20 % of its stand-alone step rate beside
    the UI although the UI used under one core of two: every parallel loop waited for its thread that the UI had
    preempted (``bench/ui.py``).

    A spawned worker sets ``NUMBA_NUM_THREADS`` before numba is imported. A worker thread inside the UI (or test)
    process never writes the process environment: numba re-reads it on every compile and refuses a value that
    differs from its launched pool, so it uses numba's per-thread ``set_num_threads`` instead."""
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)
    numba = sys.modules.get("numba")
    if numba is None and not in_thread:
        os.environ["NUMBA_NUM_THREADS"] = "1"  # numba reads it at import (the engine imports it lazily)
        return
    if numba is None:
        import numba
    try:
        numba.set_num_threads(1)  # applies to the calling thread only
    except (ValueError, RuntimeError):  # a threading layer that cannot change its size: keep it
        pass


def worker_main(factory: Callable[..., Any], config: dict[str, Any], commands: Any, events: Any, credits: Any,
                checkpoint_path: str | None, start_paused: bool, resume_from: str | None = None,
                in_thread: bool = False) -> None:
    """Entry point of the spawned process (or, with ``in_thread``, of the UI process's worker thread: no nice,
    which would apply to the whole process)."""
    _single_torch_thread(in_thread)
    if not in_thread:
        try:
            _lower_priority(int(os.environ.get("GSTYLE_WORKER_NICE", WORKER_NICE)))
        except ValueError:
            _lower_priority()
    host = _EngineHost(factory, config, events, credits, checkpoint_path)
    host.in_thread = in_thread
    host.paused = start_paused
    host.build(resume_from=resume_from)
    parent = None if in_thread else mp.parent_process()
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
        if host.should_step():
            host.step()


# ====================================================================== the UI side
class WorkerBridge:
    """Start, command and poll an engine running in a spawned process."""

    def __init__(self, factory: Callable[..., Any], config: dict[str, Any] | None = None, *,
                 checkpoint_path: str | os.PathLike | None = None, start_paused: bool = False,
                 resume_from: str | os.PathLike | None = None) -> None:
        self.factory = factory
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
        self.state.error = None
        self.state.done = False
        self.state.paused = False
        self.state.loss_history.clear()
        self.state.decisions = {}
        self.state.reports_received, self.state.step_seconds = 0, 0.0
        self.state.resumed = None
        if resume_from:
            self._send("restart_from", (self.config, str(resume_from)))
        else:
            self._send("restart", self.config)

    def set_checkpoint_path(self, path: str | os.PathLike | None) -> None:
        """Where the worker saves its checkpoint when it quits (e.g. after the scene or style changed)."""
        self.checkpoint_path = str(path) if path else None
        self._send("checkpoint_path", self.checkpoint_path)

    def set_params(self, **params: float) -> None:
        """Change engine parameters (the live controls of ``gstyle_core.pipeline.controls``: λ weights, strength,
        stroke size, keep colours, split rate, lr, style mix) from the next step on."""
        self._send("set_params", dict(params))

    def export(self, path: str | os.PathLike) -> None:
        """Ask the worker to save the stylized scene (.ply, .spz or .compressed.ply; + .json summary) at ``path``."""
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
        decisions (dict), exported (path), checkpoint (path), resumed (dict), bye.
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
                self.state.error = f"the engine process exited with code {code}"
            elif code is None and not hasattr(self._process, "exitcode"):
                self.state.error = "the engine thread stopped unexpectedly (see the console)"
        return messages

    def _apply(self, kind: str, payload: Any) -> None:
        st = self.state
        if kind == "ready":
            st.ready, st.error, st.done = True, None, False
        elif kind == "report":
            st.last_report = payload
            st.reports_received += 1
            st.step_seconds += float(payload.get("seconds") or 0.0)
            st.done = bool(payload.get("done"))
            st.loss_history.append(dict(payload.get("losses") or {}))
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
        elif kind == "error":
            st.error = payload
            st.paused = True
        elif kind == "paused":
            st.paused = bool(payload)
        elif kind == "params":
            st.params = dict(payload)
        elif kind == "decisions":
            st.decisions = dict(payload)
        elif kind == "exported":
            st.exported.append(payload)
        elif kind == "checkpoint":
            st.checkpoint = payload
        elif kind == "resumed":
            st.resumed = dict(payload)

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
