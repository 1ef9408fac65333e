"""Each frame, the engine worker's news reach the renderer (new geometry and colours, uploaded only when they
changed) and everything reaches the panel. ``StudioSync`` is a mixin of ``StudioApp``."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from .panels.quality import device_words
from .renderer import DIFFUSE_LAYER, SH_LAYER
from .result_undo import in_history

if TYPE_CHECKING:
    from .worker import WorkerState

GEOMETRY_MIN_INTERVAL_S = 0.5  # streamed geometry shown at most this often while the engine steps
GEOMETRY_DUTY = 0.1  # ... and so that its uploads take at most this share of the UI's time


def stopped_reason(st: WorkerState) -> str:
    """Why Pause / Resume and Step cannot work now ("" when they can): a worker that is gone, a finished run, or a run
    an error stopped (the panel names the ways on: Refine, Continue, the CPU, Restart)."""
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


class StudioSync:
    """``StudioApp``'s per-frame updates of its renderer and panel."""

    _run_status = ""  # the status line, when it describes the running engine (its resume, a move): ends with it
    _geometry_shown_at = 0.0  # when streamed geometry was last uploaded (perf_counter seconds)
    _geometry_cost = 0.0  # how long that upload took (s)

    def say_of_run(self, line: str) -> None:
        """A status line about the running engine: cleared when that run ends (``end_run_status``) if still shown."""
        self.panel.status = self._run_status = line

    def end_run_status(self) -> None:
        """The engine's run ends (a restart, a stop, another scene): a status line that described it goes too."""
        if self._run_status and self.panel.status == self._run_status:
            self.panel.status = ""
        self._run_status = ""

    def _apply_engine_updates(self) -> None:
        if self.bridge is None:
            return
        self.bridge.poll()
        st = self.bridge.state
        snap = st.snapshot
        if not snap:
            return
        geometry_due = (snap.get("geometry_version") != self._geometry_version and "means" in snap
                        and self._geometry_due(st))
        if st.snapshots_received == self._snapshots_seen and not geometry_due:
            return
        self._snapshots_seen = st.snapshots_received
        try:  # upload only what changed: geometry by its version, colours by theirs (c_gt changes with geometry)
            if geometry_due:
                t0 = time.perf_counter()
                self.stylized.update_geometry(snap)
                self._geometry_version = snap.get("geometry_version")
                self._geometry_shown_at = time.perf_counter()
                self._geometry_cost = self._geometry_shown_at - t0
            colour_key = (snap.get("colour_version"), self._geometry_version)
            new_colours = colour_key != self._colour_key or colour_key[0] is None
            if new_colours and "colors" in snap and len(snap["colors"]) == self.stylized.count:
                self.stylized.update_colors(snap["colors"], DIFFUSE_LAYER)
                self._colour_key = colour_key
            gt_stale = geometry_due or "gt" not in self.stylized.layers or self._geometry_version is None
            if gt_stale and "colors_gt" in snap and len(snap["colors_gt"]) == self.stylized.count:
                self.stylized.update_colors(snap["colors_gt"], "gt")
        except ValueError as exc:
            self.panel.status = f"snapshot ignored: {exc}"

    def _geometry_due(self, st: WorkerState) -> bool:
        """Whether streamed geometry is shown now. A refit changes it every step (10 a second on the demo, each
        upload re-packing every Gaussian's textures and re-sorting them): while the engine steps it is shown at most
        every ``GEOMETRY_MIN_INTERVAL_S`` and so that uploads take at most ``GEOMETRY_DUTY`` of the UI's time
        (docs/notes/studio-performance.md); the first geometry, and any once the engine stops stepping, at once."""
        if self._geometry_version is None or not st.stepping:
            return True
        wait = max(GEOMETRY_MIN_INTERVAL_S, self._geometry_cost / GEOMETRY_DUTY)
        return time.perf_counter() - self._geometry_shown_at >= wait

    def _fill_panel(self) -> None:
        p = self.panel
        p.fps = len(self._frame_times) / max(sum(self._frame_times), 1e-6)
        p.view_mode = self.view_mode
        p.fov_deg = self.control.pose.fov_y_deg
        p.has_ground_truth = "gt" in self.stylized.layers
        p.gaussians = self.stylized.count
        p.viewer_notes = self.viewer_notes()
        p.resume_available = self.resume_available()
        p.take_names = [t.name for t in self.takes.takes]
        p.take_labels = [t.label for t in self.takes.takes]
        p.take_settings = [t.settings for t in self.takes.takes]
        p.take_thumbnails = [self.take_texture(t) for t in self.takes.takes]
        p.save_folder = str(self.export_folder())
        p.undo_note = self.history.done[-1].brings_back("undo") if self.history.done else ""  # what each puts back
        p.redo_note = self.history.undone[-1].brings_back("redo") if self.history.undone else ""
        now = self.view_key()
        p.take_differs = [not now or t.view_key != now for t in self.takes.takes]
        shown = [i for i, t in enumerate(self.takes.takes) if t.path == self.take_shown]
        p.take_shown = shown[0] if shown else -1
        p.compare_with_take = self.compare_with_take and p.take_shown >= 0
        p.divider = float(self.divider)
        p.region_enabled = self.region_enabled
        mask = self.region_mask()
        p.region_mode = "rectangle" if self.region_rect_mask is not None else "box"
        if self.region_box is not None:
            p.region_box = tuple(self.region_box)
        p.region_feather = float(self.region_feather)
        p.region_selected = int(mask.sum()) if mask is not None else 0
        p.region_total = self.loaded.scene.count if self.loaded is not None else 0
        p.region_in_engine = self.engine_region if self.bridge is not None else ""
        width, height = self._view_size
        p.region_outline = self._region_outline(width, height)
        p.selection_outline = self._selection_outline(width, height)
        self._poll_video()
        if self.bridge is None:
            p.running, p.paused, p.device = False, False, ""
            p.failed, p.continue_from, p.stopped = False, None, ""
            self._show_takes_error()  # (renaming or forgetting takes needs no engine)
            return
        st = self.bridge.state
        self._fill_run(st)
        p.decisions = st.decisions
        p.loss_history = st.loss_history[-500:]
        if st.params:
            p.params.update(st.params)
        self._fill_quality(st)
        self._sync_run_lines(st)
        p.device, p.device_name, p.devices = st.device or "", st.device_name, st.devices
        self._sync_setup_note(st)
        self._sync_exports(st)
        self._show_takes_error()

    def _fill_run(self, st) -> None:
        """Whether the worker steps, why not (``stopped_reason``), the error and the ways on from it, the phase, the
        step and the ETA (only while it steps: a paused, finished or failed run has none)."""
        p = self.panel
        p.running, p.paused, p.error = st.stepping, st.paused, st.error
        p.device_failed = st.device_failed  # (cleared with the error: a new engine, a restart)
        p.failed, p.continue_from = st.failed, st.continue_from
        p.stopped = stopped_reason(st)
        rep = st.last_report
        if rep:
            p.phase = "done" if st.done else str(rep.get("phase", "-"))
            p.phase += " (stopped at an error)" if st.failed else ""
            p.step, p.total_steps = int(rep.get("step", 0)), int(rep.get("total_steps", 0))
            p.eta_seconds = self._eta(st) if st.stepping else None

    def _sync_run_lines(self, st) -> None:
        """The status lines about the running engine (``say_of_run``): it went on after an error (no longer red,
        said once as past), resumed a saved run, continued or started afresh on another device."""
        if st.went_on_after is not None:
            self.say_of_run(f"the run went on after: {st.went_on_after}")
            st.went_on_after = None
        if st.resumed is not None and st.resumed is not self._resume_seen:
            self._resume_seen = st.resumed
            session = self.session_checkpoint()
            if self._moving is not None:
                self.say_of_run(f"continued on {device_words(self._moving[0])} at step {st.resumed.get('step')}")
                self._moving = None
            else:
                what = "the last session" if session is not None and st.resumed.get("checkpoint") == str(session) \
                    else "the saved result's run"
                self.say_of_run(f"resumed {what} at step {st.resumed.get('step')}")
        if self._moving is not None and st.reports_received > self._moving[1]:
            self.say_of_run(f"started afresh on {device_words(self._moving[0])}")  # no state was taken over
            self._moving = None

    def _eta(self, st) -> float | None:
        """Seconds left: the run's plan (its steps of each kind) at the session's rate of each kind (the runs
        before a restart's included), else this run's mean so far (``plan.remaining_seconds``); without a plan, the
        mean step so far times the steps left."""
        from gstyle_core.engine.plan import remaining_seconds

        plans = st.plans or {}
        plan = plans.get("run")
        if plan:
            left = remaining_seconds(plan, st.step_times, int(plans.get("working_width", 256)), self.bridge.rates)
            if left is not None:
                return left
        if not st.reports_received:
            return None
        return st.step_seconds / st.reports_received * max(self.panel.total_steps - self.panel.step, 0)

    def _fill_quality(self, st) -> None:
        """The quality section: the preset run, each preset's estimate at the session's step rates on this
        machine (``MachineRates``: they settle), the widths."""
        from gstyle_core.engine.plan import estimate_seconds

        p = self.panel
        plans = st.plans
        if plans:
            p.preset = str(plans.get("preset", ""))
            working = int(plans.get("working_width", 256))
            p.quality_estimates = {name: estimate_seconds(plan, self.bridge.rates, working)
                                   for name, plan in plans.get("plans", {}).items()}
            p.levels = list(plans.get("levels", []))
            p.next_width = plans.get("next_width")
        rep = st.last_report or {}
        p.width = int(rep.get("width") or (p.levels[0] if p.levels else 0))
        p.refine_note = st.refine_note
        p.summary_line = str((st.summary or {}).get("line", ""))
        display = (st.summary or {}).get("display")
        ratio = display.get("speckle_ratio") if isinstance(display, dict) else None
        p.grain = "" if not isinstance(display, dict) else "-" if ratio is None else f"{float(ratio):.2f}"

    def _sync_setup_note(self, st) -> None:
        """The engine's one-off setup note to the status when it changes (the build of gsplat's CUDA module on a
        card's first run, then how long it took): the steps' progress stays still meanwhile."""
        if st.setup_note != self._setup_note_seen:
            self._setup_note_seen = st.setup_note
            if st.setup_note:
                self.panel.status = st.setup_note
        if st.setup_note and not st.last_report:  # the first step has not reported: it is the setup that runs
            self.panel.phase = "GPU setup"

    def _sync_exports(self, st) -> None:
        """New exports become takes (status: the last one); a failed export's one line goes to the status (no take
        was added: nothing was written)."""
        p = self.panel
        exports = (id(st.exported), len(st.exported))  # a restarted worker starts a new list
        if st.exported and exports != self._exports_seen:  # once per export: later messages stay visible
            new = st.exported[self._exports_seen[1]:] if exports[0] == self._exports_seen[0] else st.exported[-1:]
            self._exports_seen = exports
            new = [e for e in new if not in_history(e)]  # results saved for undo are no takes
            if new:
                self._shelve_exports(new)
                p.status = f"exported {new[-1]} (kept as {self.takes.takes[0].name})"
        failures = (id(st.export_failures), len(st.export_failures))
        if st.export_failures and failures != self._export_failures_seen:
            self._export_failures_seen = failures
            p.status = st.export_failures[-1]

    def _show_takes_error(self) -> None:
        """A failure to save ``takes.json`` (one line) after the status; the shelf goes on for this session."""
        error = self.takes.pop_write_error()
        if error:
            status = self.panel.status
            self.panel.status = f"{status}; {error} (the takes are kept for this session)" if status else error

    def viewer_notes(self) -> list[str]:
        """What the viewer evaluates and skips (panel "Decisions"): view-dependent SH, sorts, uploads."""
        renderers = (self.original, self.stylized)
        if SH_LAYER in self.original.layers:
            sh = ("viewer SH: evaluated for the original scene only, on the GPU once per camera from coefficients "
                  "uploaded once; the stylized scene is diffuse")
        else:
            sh = "viewer SH: none evaluated (the scene has no view-dependent SH)"
        sorts = sum(r.sort_count for r in renderers)
        colours = sum(r.uploads["colors"] for r in renderers)
        geometry = sum(r.uploads["geometry"] for r in renderers)
        return [sh, f"viewer work: {sorts} depth sorts (view changes only, off the UI thread), {colours} colour and "
                    f"{geometry} geometry uploads (changes only)"]
