"""Each frame, the engine worker's news reach the renderer (new geometry and colours, uploaded only when they
changed) and everything reaches the panel. ``StudioSync`` is a mixin of ``StudioApp``."""

from __future__ import annotations

from .panels.quality import device_words
from .renderer import DIFFUSE_LAYER, SH_LAYER
from .result_undo import in_history


class StudioSync:
    """``StudioApp``'s per-frame updates of its renderer and panel."""

    def _apply_engine_updates(self) -> None:
        if self.bridge is None:
            return
        self.bridge.poll()
        st = self.bridge.state
        if st.snapshots_received == self._snapshots_seen or not st.snapshot:
            return
        self._snapshots_seen = st.snapshots_received
        snap = st.snapshot
        try:  # upload only what changed: geometry by its version, colours by theirs (c_gt changes with geometry)
            new_geometry = snap.get("geometry_version") != self._geometry_version and "means" in snap
            if new_geometry:
                self.stylized.update_geometry(snap)
                self._geometry_version = snap.get("geometry_version")
            colour_key = (snap.get("colour_version"), self._geometry_version)
            new_colours = colour_key != self._colour_key or colour_key[0] is None
            if new_colours and "colors" in snap and len(snap["colors"]) == self.stylized.count:
                self.stylized.update_colors(snap["colors"], DIFFUSE_LAYER)
                self._colour_key = colour_key
            gt_stale = new_geometry or "gt" not in self.stylized.layers or self._geometry_version is None
            if gt_stale and "colors_gt" in snap and len(snap["colors_gt"]) == self.stylized.count:
                self.stylized.update_colors(snap["colors_gt"], "gt")
        except ValueError as exc:
            self.panel.status = f"snapshot ignored: {exc}"

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
        p.undo_note = self.history.done[-1].describe() if self.history.done else ""
        p.redo_note = self.history.undone[-1].describe() if self.history.undone else ""
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
            self._show_takes_error()  # (renaming or forgetting takes needs no engine)
            return
        st = self.bridge.state
        p.running, p.paused, p.error = st.alive, st.paused, st.error
        p.device_failed = st.device_failed  # (cleared with the error: a new engine, a restart)
        p.decisions = st.decisions
        p.loss_history = st.loss_history[-500:]
        if st.params:
            p.params.update(st.params)
        rep = st.last_report
        if rep:
            p.phase = "done" if st.done else str(rep.get("phase", "-"))
            p.step, p.total_steps = int(rep.get("step", 0)), int(rep.get("total_steps", 0))
            p.eta_seconds = None if st.done or st.paused else self._eta(st)  # paused: no ETA
        self._fill_quality(st)
        if st.resumed is not None and st.resumed is not self._resume_seen:
            self._resume_seen = st.resumed
            session = self.session_checkpoint()
            if self._moving is not None:
                p.status = f"continued on {device_words(self._moving[0])} at step {st.resumed.get('step')}"
                self._moving = None
            else:
                what = "the last session" if session is not None and st.resumed.get("checkpoint") == str(session) \
                    else "the saved result's run"
                p.status = f"resumed {what} at step {st.resumed.get('step')}"
        if self._moving is not None and st.reports_received > self._moving[1]:
            p.status = f"started afresh on {device_words(self._moving[0])}"  # stepping, and no state was taken over
            self._moving = None
        p.device, p.device_name, p.devices = st.device or "", st.device_name, st.devices
        self._sync_setup_note(st)
        self._sync_exports(st)
        self._show_takes_error()

    def _eta(self, st) -> float | None:
        """Seconds left: the run's plan (its steps of each kind) at the measured cost of each kind, the run
        before a restart's where this one has none yet (``plan.remaining_seconds``); without a plan, the mean step
        so far times the steps left."""
        from gstyle_core.pipeline.plan import remaining_seconds

        plans = st.plans or {}
        plan = plans.get("run")
        if plan:
            left = remaining_seconds(plan, st.step_times, int(plans.get("working_width", 256)), st.prior_times)
            if left is not None:
                return left
        if not st.reports_received:
            return None
        return st.step_seconds / st.reports_received * max(self.panel.total_steps - self.panel.step, 0)

    def _fill_quality(self, st) -> None:
        """The quality section: the preset run, each preset's estimate at this run's step times, the widths."""
        from gstyle_core.pipeline.plan import estimate_seconds

        p = self.panel
        plans = st.plans
        if plans:
            p.preset = str(plans.get("preset", ""))
            working = int(plans.get("working_width", 256))
            p.quality_estimates = {name: estimate_seconds(plan, st.step_times, working)
                                   for name, plan in plans.get("plans", {}).items()}
            p.levels = list(plans.get("levels", []))
            p.next_width = plans.get("next_width")
        rep = st.last_report or {}
        p.width = int(rep.get("width") or (p.levels[0] if p.levels else 0))
        p.refine_note = st.refine_note
        p.summary_line = str((st.summary or {}).get("line", ""))

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
