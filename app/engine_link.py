"""The studio's link to the engine: its factory and config, the worker bridge (``app/worker.py``) that runs it,
starting, stopping, moving and continuing it, the session checkpoint it resumes from and this machine's step rates.
What reaches the renderer and the panel each frame is ``EngineSync``'s (``app/studio_sync.py``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gstyle_core.engine.plan import MachineRates
from gstyle_core.style.clip import clip_term_name

from .events import Events, Handlers, RunReplacing, RunStarted, RunStopped, SceneShown
from .panels import PanelState
from .panels.quality import device_words
from .status_line import StatusLine
from .worker import ThreadWorkerBridge, WorkerBridge, WorkerState

REGION_KEYS = ("region", "selection", "region_feather")  # what the region tool hands the engine's config


class EngineLink:
    """Owns the engine's factory, config and bridge. Built with the panel, the status line, the events (it tells of
    runs replaced, started and stopped), the worker mode ("process", the default, or "thread": bench/ui.py) and
    ``region_entries`` (the region tool's selection as config entries, taken when an engine starts)."""

    def __init__(self, panel: PanelState, status: StatusLine, events: Events, *,
                 factory: Callable[..., Any] | None, config: dict[str, Any] | None, worker_mode: str,
                 region_entries: Callable[[], dict[str, Any]]) -> None:
        self.panel, self.status, self.events = panel, status, events
        self.factory = factory
        self.config = dict(config or {})
        self.worker_mode = worker_mode
        self.region_entries = region_entries
        self.bridge: WorkerBridge | None = None
        self._rates: dict[tuple[str, str], MachineRates] = {}  # step rates per (scene, device) (``session_rates``)
        self._bridge_seen: tuple[bool, str | None] | None = None  # (alive, error) last seen by ``news``
        self._resumed_from: Path | None = None  # the session checkpoint this engine continued from
        self._resume_seen: Any = None  # the last resume report shown in the status line
        self._moving: tuple[str, int] | None = None  # a move to another device asked: the device and the reports
        # received then (its resume report, or a step without one, says how it went on)
        self._resume_probe: tuple[float, Path | None, bool] = (0.0, None, False)  # (time, path, exists)
        panel.clip_name = clip_term_name(self.config.get("clip_weights"))
        panel.quality = str(self.config.get("preset") or "preview")
        events.subscribe(SceneShown, self._scene_shown)

    def _scene_shown(self, event: SceneShown) -> None:
        """The config's scene; a result shown: the quality chosen follows its tier (what its restarts run)."""
        self.config["scene"] = event.loaded.path
        if event.result is not None and event.result.preset:
            self.set_quality(event.result.preset)

    # ----------------------------------------------------------------- config
    def configure(self, **entries: Any) -> None:
        """Set entries of the engine's config (the next start uses them)."""
        self.config.update(entries)

    def set_style(self, style: str | list[str] | None, weights: tuple[float, float] | None) -> None:
        """The config's painting(s) (``style``) and their weights (None: one painting, no weights)."""
        self.config["style"] = style
        if weights is None:
            self.config.pop("style_weights", None)
        else:
            self.config["style_weights"] = weights

    def take_region(self) -> None:
        """The region tool's selection as it is now into the config (a box as ``region``, a rectangle as a
        ``selection`` mask; nothing while the tool is off)."""
        for key in REGION_KEYS:
            self.config.pop(key, None)
        self.config.update(self.region_entries())

    def choose_quality(self, preset: str) -> None:
        """The quality chosen in the panel (the next fresh start runs it: ``start``)."""
        self.panel.quality = preset

    def set_quality(self, preset: str) -> None:
        """The quality the next start runs at, chosen in the panel too."""
        self.config["preset"] = preset
        self.panel.quality = preset

    # ----------------------------------------------------------------- the session's checkpoint and rates
    def session_checkpoint(self) -> Path | None:
        """Where the session of this scene + style is saved when the studio closes (cache folder), or None."""
        from gstyle_core.engine.checkpoint import studio_checkpoint_path

        scene = self.config.get("scene")
        return studio_checkpoint_path(scene, self.config.get("style")) if scene else None

    def resume_available(self) -> bool:
        """True when a saved session of this scene + style exists and this engine did not start from it."""
        now, path = time.monotonic(), self.session_checkpoint()
        when, probed, exists = self._resume_probe
        if probed != path or now - when > 1.0:  # one stat a second at most
            exists = path is not None and path.is_file()
            self._resume_probe = (now, path, exists)
        if self.bridge is not None and self.bridge.state.alive and self.bridge.state.autosaved is not None:
            return False  # the running engine saved it itself: resuming it would go back, not on
        return exists and self.factory is not None and self._resumed_from != path

    def died_at(self) -> int | None:
        """The step the run can go on from after its worker died (killed, or a crash of the process): the step of
        the session it saved last, or of the session it resumed from; None while it lives or nothing was saved."""
        bridge = self.bridge
        if bridge is None or bridge.state.alive or not bridge.state.error or self.factory is None:
            return None
        path, st = self.session_checkpoint(), bridge.state
        if path is None or not path.is_file():
            return None
        if st.autosaved is not None and st.autosaved.get("path") == str(path):
            return int(st.autosaved["step"])
        resumed = st.resumed or {}
        return int(resumed["step"]) if resumed.get("checkpoint") == str(path) and resumed.get("step") is not None \
            else None

    def session_rates(self) -> MachineRates:
        """This machine's step rates for the scene and the device the engine runs with now, kept over the session
        (restarts, other qualities, results opened in between): what the quality choice prices the presets at."""
        key = (str(self.config.get("scene") or ""), str(self.config.get("device") or "auto"))
        return self._rates.setdefault(key, MachineRates())

    # ----------------------------------------------------------------- the run
    def start(self, resume: bool = False, action: str = "restart", resume_from: Path | None = None) -> bool:
        """Spawn the engine worker with the current scene/style config (restarts it if running; a stylized result
        it replaces is saved first and becomes a step back, ``action`` naming what replaced it: ``RunReplacing``).

        ``resume``: continue from the saved session of this scene + style; returns False when there is none (the
        engine then starts afresh). ``resume_from``: continue from that checkpoint instead (a result's kept run).
        Whether the checkpoint fits (same inputs and settings) the worker checks."""
        if self.factory is None:
            return False
        self.events.publish(RunReplacing(action))
        self.status.end_run()
        self.take_region()
        path = self.session_checkpoint()
        if resume_from is None and resume and path is not None and path.is_file():
            resume_from = path
        self._resumed_from = resume_from
        if resume_from is None:  # a fresh start runs the quality chosen (a loaded run keeps its own)
            self.config["preset"] = self.panel.quality
        if self.bridge is None:
            bridge_class = ThreadWorkerBridge if self.worker_mode == "thread" else WorkerBridge
            self.bridge = bridge_class(self.factory, self.config, checkpoint_path=path, resume_from=resume_from,
                                       rates=self.session_rates())
            self.bridge.start()
        else:
            self.bridge.set_checkpoint_path(path)
            self.bridge.rates = self.session_rates()
            self.bridge.restart(self.config, resume_from=resume_from)
        if resume_from is not None:
            what = "the last session" if resume_from == path else "this result's run"
            self.status.say_of_run(f"resuming {what} ({resume_from.name}) ...")
        self.events.publish(RunStarted())
        return resume_from is not None

    def stop(self, timeout: float = 20.0) -> None:
        """Stop the running engine (its session is saved as on close; a stylized result becomes a step back); the
        view keeps what it shows."""
        if self.bridge is not None:
            self.events.publish(RunReplacing("stop"))
            self.bridge.quit(timeout)
            self.bridge = None
            self.events.publish(RunStopped())
            self.status.end_run()

    def quit(self, timeout: float = 20.0) -> bool:
        """The studio closes: the engine saves the session (killed after ``timeout`` s); False when it had to be
        killed (nothing saved)."""
        return self.bridge.quit(timeout) if self.bridge is not None else True

    def move_to(self, device: str) -> None:
        """Go on on ``device`` from where the run is (the CPU after the GPU failed, or the GPU / the CPU when the
        artist moves it); later restarts stay there."""
        self.config["device"] = device
        if self.bridge is None:
            return
        self.bridge.rates = self.session_rates()  # another device's step rates are its own
        self.bridge.move_to(self.config, device)
        self._moving = (device, self.bridge.state.reports_received)  # (a worker started again counts from 0)
        self.status.say_of_run(f"moving the run to {device_words(device)} ...")

    def continue_run(self) -> None:
        """After an engine error: go on from the run's last finished step on the device it is on (the worker builds
        the engine again from the run's state; the status then says where it continued, as after a move)."""
        if self.bridge is None:
            return
        st = self.bridge.state
        device, step = st.device or str(self.config.get("device") or "cpu"), st.continue_from
        self.bridge.continue_run()
        self._moving = (device, st.reports_received)
        self.status.say(f"continuing from step {step} ...")

    def refine(self) -> None:
        """Carry the run on at its next finer level (the result it had becomes a step back)."""
        if self.bridge is not None:
            self.events.publish(RunReplacing("refine"))
            self.bridge.refine()

    def set_params(self, values: dict[str, float]) -> None:
        """Controls to the running engine (from its next step)."""
        if self.bridge is not None:
            self.bridge.set_params(**values)

    def news(self) -> bool:
        """Whether the worker sent anything, or came or went, since the last look (render on demand)."""
        if self.bridge is None:
            return False
        news = bool(self.bridge.poll())
        key = (self.bridge.state.alive, self.bridge.state.error)
        news, self._bridge_seen = news or key != self._bridge_seen, key
        return news

    def view_key(self) -> str:
        """What the stylized view shows now: the engine run and its geometry and colour versions ("" before any)."""
        st = self.bridge.state if self.bridge is not None else None
        snap = st.snapshot if st is not None else None
        if not snap:
            return ""
        return f"{id(st.exported)}:{snap.get('geometry_version')}:{snap.get('colour_version')}"

    def say_run_news(self, st: WorkerState) -> None:
        """The status lines about the running engine (``say_of_run``): it went on after an error (no longer red,
        said once as past), resumed a saved run, continued or started afresh on another device."""
        went_on_after = st.take_went_on_after()
        if went_on_after is not None:
            self.status.say_of_run(f"the run went on after: {went_on_after}")
        if st.resumed is not None and st.resumed is not self._resume_seen:
            self._resume_seen = st.resumed
            session = self.session_checkpoint()
            if self._moving is not None:
                self.status.say_of_run(f"continued on {device_words(self._moving[0])} at step "
                                       f"{st.resumed.get('step')}")
                self._moving = None
            else:
                what = "the last session" if session is not None and st.resumed.get("checkpoint") == str(session) \
                    else "the saved result's run"
                self.status.say_of_run(f"resumed {what} at step {st.resumed.get('step')}", in_terminal=True)
        if self._moving is not None and st.reports_received > self._moving[1]:
            self.status.say_of_run(f"started afresh on {device_words(self._moving[0])}")  # no state was taken over
            self._moving = None

    def fill_panel(self) -> None:
        """Whether a saved session could be resumed, and from which step after the worker died."""
        self.panel.resume_step = self.died_at()
        self.panel.resume_available = self.panel.resume_step is not None or self.resume_available()

    def _ask_worker(self, name: str) -> None:
        """Pause, resume or step the running engine (nothing without one)."""
        if self.bridge is not None:
            {"pause": self.bridge.pause, "resume": self.bridge.resume, "step": self.bridge.step_once}[name]()

    def commands(self) -> Handlers:
        """The panel's commands this part carries out: pause, resume, step, restart, resume the session, move,
        continue, the quality chosen, refine."""
        return {"pause": lambda _args: self._ask_worker("pause"), "resume": lambda _args: self._ask_worker("resume"),
                "step": lambda _args: self._ask_worker("step"),
                "restart": lambda _args: self.start(), "resume_session": lambda _args: self.start(resume=True),
                "move_to": lambda args: self.move_to(str(args["device"])),
                "continue_run": lambda _args: self.continue_run(),
                "set_quality": lambda args: self.choose_quality(str(args["preset"])),
                "refine": lambda _args: self.refine()}
