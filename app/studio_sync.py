"""Each frame, the engine worker's news reach the stylized renderer (new geometry and colours, uploaded only when
they changed) and the run's fields of the panel (``EngineSync``, a part of ``StudioApp``: the engine link's other
half, ``app/engine_link.py``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from .engine_link import EngineLink
from .events import Events, RunStarted, RunStopped, SceneShown
from .panels import PanelState
from .renderer import DIFFUSE_LAYER, SplatRenderer
from .result_undo import in_history
from .status_line import StatusLine
from .worker import WorkerState

GEOMETRY_MIN_INTERVAL_S = 0.5  # streamed geometry shown at most this often while the engine steps
GEOMETRY_DUTY = 0.1  # ... and so that its uploads take at most this share of the UI's time


def stopped_reason(st: WorkerState, resume_step: int | None = None) -> str:
    """Why Pause / Resume and Step cannot work now ("" when they can): a worker that is gone (``resume_step``: the
    step its last save holds, ``EngineLink.died_at``), a finished run, or a run an error stopped (the panel names the
    ways on: Resume, Refine, Continue, the CPU, Restart)."""
    if not st.alive and resume_step is not None:
        return (f"The engine process is gone: Resume from step {resume_step} (or Space) goes on from its last save; "
                "Restart starts again.")
    if not st.alive:
        return "The engine is not running: Restart starts it again."
    if st.done and not st.failed:
        return "The run is done: Refine carries it on at a finer width; Restart starts it again."
    if not st.failed:
        return ""
    if st.continue_from is not None:
        way = f"Continue goes on from step {st.continue_from}, the last finished one; Restart starts again."
    elif st.device_failed:
        way = "Continue on the CPU goes on from where it stopped; Restart starts again."
    else:
        way = "Restart starts again."
    return f"The run stopped at an error (above): {way}"


class EngineSync:
    """Each frame, the worker's news into the stylized renderer and the run's fields of the panel (its progress,
    quality, device, the setup note, new exports). Built with the panel, the status line, the events (it follows
    scenes shown and runs started and stopped), the engine link, the stylized renderer, ``showing_result`` (a
    stylized result is on show) and ``shelve`` (new exports become takes; returns the newest take's name)."""

    def __init__(self, panel: PanelState, status: StatusLine, events: Events, engine: EngineLink,
                 stylized: SplatRenderer, showing_result: Callable[[], bool],
                 shelve: Callable[[list[str]], str]) -> None:
        self.panel, self.status, self.engine, self.stylized = panel, status, engine, stylized
        self.showing_result, self.shelve = showing_result, shelve
        self._snapshots_seen = 0
        self._geometry_version: Any = None
        self._colour_key: Any = None  # (colour_version, geometry_version) of the colours last uploaded
        self._geometry_shown_at = 0.0  # when streamed geometry was last uploaded (perf_counter seconds)
        self._geometry_cost = 0.0  # how long that upload took (s)
        self._exports_seen: tuple[int, int] = (0, 0)
        self._setup_note_seen = ""
        self._export_failures_seen: tuple[int, int] = (0, 0)  # the same for failed exports (their one line)
        events.subscribe(SceneShown, self._scene_shown)
        events.subscribe(RunStarted, self._run_started)
        events.subscribe(RunStopped, self._run_stopped)

    def _scene_shown(self, event: SceneShown) -> None:
        """Another scene: its geometry and colours come anew; a result shows its own phase and widths."""
        self._geometry_version = self._colour_key = None
        info = event.result
        if info is not None:
            p = self.panel
            p.phase, p.preset = "result (nothing running)", info.preset  # the result's own tier and widths
            p.levels, p.width = list(info.levels), (info.levels[-1] if info.levels else 0)

    def _run_started(self, _event: RunStarted) -> None:
        """A new engine counts its versions from 0 again; the run before's progress goes with it (the new run's
        first report says its own)."""
        self._snapshots_seen = 0
        self._geometry_version = self._colour_key = None
        p = self.panel
        p.phase, p.step, p.total_steps, p.eta_seconds = "starting", 0, 0, None
        p.preset = ""  # the tier of what was on show goes with it (the new run's plans say its own)

    def _run_stopped(self, _event: RunStopped) -> None:
        """What the stopped run showed goes with it."""
        p = self.panel
        p.step, p.total_steps, p.eta_seconds, p.loss_history = 0, 0, None, []
        p.phase = "result (nothing running)" if self.showing_result() else "stopped"
        p.summary_line, p.grain, p.refine_note, p.next_width = "", "", "", None
        if not self.showing_result():  # no run's width or tier to show (a result on show shows its own)
            p.width, p.levels, p.preset = 0, [], ""

    def apply_updates(self) -> None:
        """The engine's newest snapshot into the stylized renderer: geometry by its version (streamed geometry at
        most as often as ``_geometry_due`` allows; at once the first after a change of the artist's the worker took:
        ``ArtistParams.view_owed``), colours by theirs."""
        bridge = self.engine.bridge
        if bridge is None:
            return
        bridge.poll()
        st = bridge.state
        snap = st.snapshot
        if not snap:
            return
        owed = st.artist.view_owed(st.snapshots_received)  # the artist's change: shown at once, not streamed
        geometry_due = (snap.get("geometry_version") != self._geometry_version and "means" in snap
                        and (owed or self._geometry_due(st)))
        if st.snapshots_received == self._snapshots_seen and not geometry_due:
            return
        self._snapshots_seen = st.snapshots_received
        stylized = self.stylized
        try:  # upload only what changed: geometry by its version, colours by theirs (c_gt changes with geometry)
            if geometry_due:
                t0 = time.perf_counter()
                stylized.update_geometry(snap)
                self._geometry_version = snap.get("geometry_version")
                self._geometry_shown_at = time.perf_counter()
                self._geometry_cost = self._geometry_shown_at - t0
            colour_key = (snap.get("colour_version"), self._geometry_version)
            new_colours = colour_key != self._colour_key or colour_key[0] is None
            if new_colours and "colors" in snap and len(snap["colors"]) == stylized.count:
                stylized.update_colors(snap["colors"], DIFFUSE_LAYER)
                self._colour_key = colour_key
            gt_stale = geometry_due or "gt" not in stylized.layers or self._geometry_version is None
            if gt_stale and "colors_gt" in snap and len(snap["colors_gt"]) == stylized.count:
                stylized.update_colors(snap["colors_gt"], "gt")
            if owed:
                st.artist.view_shown()
        except ValueError as exc:
            self.status.say(f"snapshot ignored: {exc}")

    def _geometry_due(self, st: WorkerState) -> bool:
        """Whether streamed geometry is shown now. A refit changes it every step (10 a second on the demo, each
        upload re-packing every Gaussian's textures and re-sorting them): while the engine steps it is shown at most
        every ``GEOMETRY_MIN_INTERVAL_S`` and so that uploads take at most ``GEOMETRY_DUTY`` of the UI's time
        (docs/notes/studio-performance.md); the first geometry, and any once the engine stops stepping, at once."""
        if self._geometry_version is None or not st.stepping:
            return True
        wait = max(GEOMETRY_MIN_INTERVAL_S, self._geometry_cost / GEOMETRY_DUTY)
        return time.perf_counter() - self._geometry_shown_at >= wait

    def fill_panel(self) -> None:
        """The run's fields of the panel (nothing running: none), and the status lines of its news."""
        p, bridge = self.panel, self.engine.bridge
        if bridge is None:
            p.running, p.paused, p.device = False, False, ""
            p.failed, p.continue_from, p.stopped = False, None, ""
            return
        st = bridge.state
        self._fill_run(st)
        p.decisions = st.decisions
        p.loss_history = st.loss_history[-500:]
        p.params.update(st.artist.engine_values(st.params))  # a control the worker has not taken: the artist's
        self._fill_quality(st)
        self.engine.say_run_news(st)
        p.device, p.device_name, p.devices = st.device or "", st.device_name, st.devices
        self._sync_setup_note(st)
        self._sync_exports(st)

    def _fill_run(self, st: WorkerState) -> None:
        """Whether the worker steps, why not (``stopped_reason``), the error and the ways on from it, the phase, the
        step and the ETA (only while it steps: a paused, finished or failed run has none)."""
        p = self.panel
        p.running, p.paused, p.error = st.stepping, st.paused, st.error
        p.device_failed = st.device_failed  # (cleared with the error: a new engine, a restart)
        p.failed, p.continue_from = st.failed, st.continue_from
        p.stopped = stopped_reason(st, p.resume_step)  # (the engine link filled resume_step first)
        rep = st.last_report
        if rep:
            p.phase = "done" if st.done else str(rep.get("phase", "-"))
            p.phase += " (stopped at an error)" if st.failed else ""
            p.step, p.total_steps = int(rep.get("step", 0)), int(rep.get("total_steps", 0))
            p.eta_seconds = self._eta(st) if st.stepping else None

    def _eta(self, st: WorkerState) -> float | None:
        """Seconds left: the run's plan (its steps of each kind) at the session's rate of each kind (the runs
        before a restart's included), else this run's mean so far, else guessed (``plan.remaining_seconds``); without a
        plan, the mean step so far times the steps left."""
        from gstyle_core.engine.plan import remaining_seconds

        plans = st.plans or {}
        plan = plans.get("run")
        if plan:
            rates = self.engine.bridge.rates
            return remaining_seconds(plan, st.step_times, int(plans.get("working_width", 256)), rates)  # (None:
            # measuring; the mean step so far would promise a fraction: the first steps are the cheap ones)
        if not st.reports_received:
            return None
        return st.step_seconds / st.reports_received * max(self.panel.total_steps - self.panel.step, 0)

    def _fill_quality(self, st: WorkerState) -> None:
        """The quality section: the preset run, each preset's estimate at the session's step rates on this
        machine (``MachineRates``: they settle), the widths."""
        from gstyle_core.engine.plan import estimate_seconds

        p = self.panel
        plans = st.plans
        if plans:
            p.preset = str(plans.get("preset", ""))
            working = int(plans.get("working_width", 256))
            p.quality_estimates = {name: estimate_seconds(plan, self.engine.bridge.rates, working)
                                   for name, plan in plans.get("plans", {}).items()}
            p.levels = list(plans.get("levels", []))
            p.next_width = plans.get("next_width")
        p.width = st.width or (p.levels[0] if p.levels else 0)  # the newest of the report's and the plans' (a run
        # continued or refined says its width before its next step)
        p.refine_note = st.refine_note
        p.summary_line = str((st.summary or {}).get("line", ""))
        display = (st.summary or {}).get("display")
        ratio = display.get("speckle_ratio") if isinstance(display, dict) else None
        p.grain = "" if not isinstance(display, dict) else "-" if ratio is None else f"{float(ratio):.2f}"

    def _sync_setup_note(self, st: WorkerState) -> None:
        """The engine's one-off setup note to the status when it changes (the build of gsplat's CUDA module on a
        card's first run, then how long it took): the steps' progress stays still meanwhile."""
        if st.setup_note != self._setup_note_seen:
            self._setup_note_seen = st.setup_note
            if st.setup_note:
                self.status.say(st.setup_note)
        if st.setup_note and not st.last_report:  # the first step has not reported: it is the setup that runs
            self.panel.phase = "GPU setup"

    def _sync_exports(self, st: WorkerState) -> None:
        """New exports become takes (status: the last one); a failed export's one line goes to the status (no take
        was added: nothing was written)."""
        exports = (id(st.exported), len(st.exported))  # a restarted worker starts a new list
        if st.exported and exports != self._exports_seen:  # once per export: later messages stay visible
            new = st.exported[self._exports_seen[1]:] if exports[0] == self._exports_seen[0] else st.exported[-1:]
            self._exports_seen = exports
            new = [e for e in new if not in_history(e)]  # results saved for undo are no takes
            if new:
                kept = self.shelve(new)
                self.status.say(f"exported {new[-1]} (kept as {kept})")
        failures = (id(st.export_failures), len(st.export_failures))
        if st.export_failures and failures != self._export_failures_seen:
            self._export_failures_seen = failures
            self.status.say(st.export_failures[-1])
