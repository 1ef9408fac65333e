"""The studio's panel commands, and the outputs it starts: exports (written by the engine worker) and turntable
videos (a background job). ``StudioCommands`` is a mixin of ``StudioApp``."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from gstyle_core.assets import DEMO_SCENE
from gstyle_core.engine.controls import painting_controls
from gstyle_core.engine.kept_runs import copy_result_state
from gstyle_core.errors import GStyleError
from gstyle_core.outputs import SUMMARY, unused_name
from gstyle_core.scene import GaussianScene

from .export import EXPORT_SUFFIXES, export_shown_result
from .panels import Command
from .panels.quality import device_words
from .snapshot import has_scene, scene_from_snapshot
from .video_job import VideoJob, turntable_path

TURNTABLE_WIDTH = 640


class StudioCommands:
    """``StudioApp``'s command execution (``execute``), exports and turntable videos."""

    def execute(self, cmd: Command) -> None:
        """Carry out one panel command."""
        for group in (self._engine_command, self._view_command, self._output_command, self._take_command):
            if group(cmd.name, cmd.args):
                return
        self._file_command(cmd.name, cmd.args)  # open buttons and the file browser (app/open_files.py)

    def _engine_command(self, name: str, args: dict[str, Any]) -> bool:
        """Pause, resume, step, restart, resume the session, set parameters, drop the second painting."""
        bridge = self.bridge
        if name in ("pause", "resume", "step"):
            if bridge is not None:
                {"pause": bridge.pause, "resume": bridge.resume, "step": bridge.step_once}[name]()
        elif name == "restart":
            self.start_engine()
        elif name == "restart_from_original":
            self.restart_from_original()
        elif name == "continue_result":
            self.continue_result()
        elif name == "resume_session":
            self.start_engine(resume=True)
        elif name == "move_to":
            self.move_to(str(args["device"]))
        elif name == "continue_run":
            self.continue_run()
        elif name == "set_params":
            self.history.record({k: self.panel.params.get(k) for k in args}, args)
            self._apply_params(args)
        elif name in ("undo", "redo"):
            self.undo_or_redo(name)
        elif name == "set_quality":
            self.panel.quality = str(args["preset"])
        elif name == "restart_quality":
            before, last_step = self.choice_state("quality"), self.history.last()
            self.engine_config["preset"] = str(args["preset"])
            self.panel.quality = str(args["preset"])
            self.panel.status = f"restarting at the {args['preset']} quality"
            self.start_engine()
            self.choice_step("quality", before, last_step)
        elif name == "refine":
            if bridge is not None:
                self.keep_result("refine")
                bridge.refine()
        elif name == "remove_style2":
            before, last_step = self.painting_state(), self.history.last()
            self.remove_second_style()
            self.panel.status = "back to one painting"
            if bridge is not None:
                self.start_engine()
            self.choice_step("painting", before, last_step)
        else:
            return False
        return True

    def move_to(self, device: str) -> None:
        """Go on on ``device`` from where the run is (the CPU after the GPU failed, or the GPU / the CPU when the
        artist moves it); later restarts stay there."""
        self.engine_config["device"] = device
        if self.bridge is None:
            return
        self.bridge.rates = self.session_rates()  # another device's step rates are its own
        self.bridge.move_to(self.engine_config, device)
        self._moving = (device, self.bridge.state.reports_received)  # (a worker started again counts from 0)
        self.say_of_run(f"moving the run to {device_words(device)} ...")

    def continue_run(self) -> None:
        """After an engine error: go on from the run's last finished step on the device it is on (the worker builds
        the engine again from the run's state; the status then says where it continued, as after a move)."""
        if self.bridge is None:
            return
        st = self.bridge.state
        device, step = st.device or str(self.engine_config.get("device") or "cpu"), st.continue_from
        self.bridge.continue_run()
        self._moving = (device, st.reports_received)
        self.panel.status = f"continuing from step {step} ..."

    def restart_from_original(self) -> None:
        """A result is on show: open the scene it came from and stylize it with the result's preset and the
        painting(s) and controls shown (the result's, ``show_result_painting``, or what the artist chose since); the
        weights a studio Refine's level set go back to the preset's unless the artist moved them."""
        info = self.result
        if info is None or info.source is None:
            self.panel.status = "the original scene of this result was not found"
            return
        if info.preset:
            self.engine_config["preset"] = info.preset
        shown = {k: v for k, v in self.panel.params.items() if k in info.params}  # the original resets the panel
        for name, (level, preset) in info.level_weights.items():  # a Refine's level set these: not the preset's
            if shown.get(name) == level:  # (the artist's own value, moved since, stays)
                shown[name] = preset
        if self.open_path(str(info.source)) and self.bridge is None:
            self.start_engine()
        self._apply_params({k: v for k, v in shown.items() if k in self.panel.params})  # from the first step

    def continue_result(self) -> None:
        """A result whose run was kept (``engine/kept_runs.py``) was opened: open its original and paintings, put its
        region back, and start the engine from that run (where it ended; nothing is stylized again)."""
        info = self.result
        if info is None or info.state is None or info.source is None:
            self.panel.status = "this result's run was not kept or its original is missing: Restart from the original"
            return
        state, config = info.state, info.state_config
        if info.preset:
            self.engine_config["preset"] = info.preset
        for slot, painting in enumerate(info.styles[:2]):
            self.open_path(str(painting), style_slot=slot, record=False)
        if not self.open_path(str(info.source)):
            return
        if config.get("region"):
            self.enable_region(True)
            self.set_region_box(tuple(float(v) for v in config["region"]))
            self.region_feather = float(config.get("region_feather") or 0.0)
        self.start_engine(action="continue", resume_from=state)

    def _apply_params(self, values: dict[str, float]) -> None:
        """Controls to the panel and the engine (from the next step; a finished run's switch back returns its
        colours)."""
        self.panel.params.update(values)
        if painting_controls() & values.keys() and self.panel.style2_path:  # a restarted engine keeps the mix
            self._update_style_config()
        if self.bridge is not None:
            self.bridge.set_params(**values)

    def _view_command(self, name: str, args: dict[str, Any]) -> bool:
        """View mode, field of view, camera (reset, frame all, scene cameras), help, and the region tool."""
        if name == "view_mode":
            self.set_view_mode(args["mode"])
        elif name == "fov":
            self.control.set_fov(args["degrees"])
        elif name == "reset_camera":
            self.control.reset()
            if self._framed is not None:  # a framed home: framed again for the view's size now
                self._framed = (None, self.control.version)
        elif name == "frame_all":
            self.frame_all()
        elif name == "snap_camera":
            if args["index"] < len(self.cameras):
                cam = self.cameras[args["index"]]
                self.control.snap_to(cam)
                self.panel.camera_index = args["index"]
                self.panel.status = f"camera {args['index'] + 1}: {cam.name}"
        elif name == "region_enable":
            self.enable_region(bool(args.get("on", True)))
        elif name == "region_box":
            self.set_region_box(args["box"])
        elif name == "region_feather":
            self.region_feather = max(0.0, float(args["value"]))
        elif name == "region_fit":
            self.set_region_box(self.scene_box())
        elif name == "toggle_help":
            self.panel.show_help = not self.panel.show_help
        elif name == "quit":  # the frame loop ends as for the close button (the session is saved on close)
            self.quit_requested = True
        else:
            return False
        return True

    def _output_command(self, name: str, args: dict[str, Any]) -> bool:
        """Screenshot, export, turntable video (start, settings, cancel)."""
        if name == "screenshot":
            self.request_screenshot(scene_only=bool(args.get("scene_only", False)))
        elif name == "export":
            self.export(fmt=args.get("format", "ply"))
        elif name == "turntable":
            self.start_turntable(args.get("frames", self.panel.turntable_frames),
                                 args.get("format", self.panel.turntable_format))
        elif name == "turntable_settings":
            self.panel.turntable_frames = int(args.get("frames", self.panel.turntable_frames))
            self.panel.turntable_format = str(args.get("format", self.panel.turntable_format))
        elif name == "cancel_video":
            if self.video_job is not None:
                self.video_job.cancel()
        else:
            return False
        return True

    def _take_command(self, name: str, args: dict[str, Any]) -> bool:
        """Show, compare, rename or forget a take."""
        if name == "show_take":
            self.show_take(int(args["index"]), compare=bool(args.get("compare", True)))
        elif name == "compare_original":
            self.compare_with_original()
        elif name == "rename_take":
            self.takes.rename(int(args["index"]), str(args["name"]))
        elif name == "forget_take":
            self.forget_take(int(args["index"]))
        else:
            return False
        return True

    def request_screenshot(self, scene_only: bool = False) -> Path:
        """Save a screenshot at the end of this frame: the whole window (``screenshot_STAMP.png``) or the scene view
        alone, without panel and overlays (``scene_only``: ``scene_STAMP.png``); never over an earlier one."""
        stamp = time.strftime("%Y%m%d_%H%M%S")
        path = unused_name(self.output_dir / f"{'scene' if scene_only else 'screenshot'}_{stamp}.png")
        if (path, scene_only) not in self.screenshot_requests:  # twice in one frame: one file
            self.screenshot_requests.append((path, scene_only))
        return path

    def export(self, path: str | Path | None = None, fmt: str = "ply") -> None:
        """Export the stylized scene (``fmt`` "ply", "spz", "compressed-ply" or "sog", + .json) through the worker; with
        no engine running, the result on show (reopened or brought back by undo) is saved as it is."""
        shown_result = self.result is not None and self.loaded is not None
        if (self.bridge is None or not self.bridge.alive) and not shown_result:
            self.panel.status = "export: no engine is running and no result is shown"
            return
        suffix = EXPORT_SUFFIXES[fmt]
        if not path:  # a name of its own: an earlier export of this second (another format) keeps its summary
            stamped = self.export_folder() / f"stylized_{time.strftime('%Y%m%d_%H%M%S')}{suffix}"
            path = unused_name(stamped, (SUMMARY,))
        path = Path(path)
        if self.bridge is None or not self.bridge.alive:
            self._save_shown_result(path)
            return
        self.bridge.export(path)
        self.panel.status = f"exporting {path} ..."

    def _save_shown_result(self, path: Path) -> None:
        """Write the result on show (no engine) under ``path`` and shelve it as a take, as an engine's export is."""
        try:
            export_shown_result(self.loaded.scene, self.result.summary, path)
        except GStyleError as exc:
            self.panel.status = f"export: {exc}"
            return
        try:  # its run goes with it, so the copy can be continued too
            copy_result_state(self.loaded.path, path)
        except OSError as exc:
            print(f"gstyle-studio: saved, but its run was not copied: {exc}", flush=True)
        self._shelve_exports([str(path)])
        self.panel.status = f"saved {path} (kept as {self.takes.takes[0].name})"

    def export_folder(self) -> Path:
        """Where Ctrl+S and the export buttons write: the folder saved to last (Save As, or ``--output-dir``), else
        beside the scene the artist opened (not the bundled demo's folder; one that can be written), else the
        output folder."""
        if self.save_folder is not None:
            return self.save_folder
        scene = Path(self.loaded.path) if self.loaded is not None else None
        if (scene is not None and scene.is_file() and scene.resolve().parent != DEMO_SCENE.resolve().parent
                and os.access(scene.parent, os.W_OK)):
            return scene.parent
        return self.output_dir

    def save_as(self, path: str | Path) -> None:
        """Save As: export to ``path`` (the engine writes the format its suffix names) and write there from now
        on."""
        path = Path(path)
        self.save_folder = path.parent
        self.export(path)

    def current_scene(self) -> GaussianScene | None:
        """The stylized scene as the engine last sent it (diffuse colours), else the loaded scene (with its SH)."""
        snap = self.bridge.state.snapshot if self.bridge is not None else {}
        if has_scene(snap):
            return scene_from_snapshot(snap)
        return self.loaded.scene if self.loaded is not None else None

    def start_turntable(self, frames: int, fmt: str = "mp4", path: str | Path | None = None) -> Path | None:
        """Render a turntable of the current scene into the output folder in the background (``VideoJob``);
        the panel shows its progress. Returns where it will be written (None when it cannot start)."""
        from gstyle_core.render_video import cameras_up, turntable_cameras

        scene = self.current_scene()
        if scene is None or scene.count == 0:
            self.panel.status = "turntable: no scene"
            return None
        if self.video_job is not None and self.video_job.running:
            self.panel.status = "turntable: a video is already rendering"
            return None
        size = (TURNTABLE_WIDTH, TURNTABLE_WIDTH * 3 // 4)
        if self.cameras:  # the scene cameras' aspect and the way they stand
            first = self.cameras[0].resized_to_width(TURNTABLE_WIDTH)
            size = (first.width, first.height)
        up = cameras_up(self.cameras) if self.cameras else "-y"
        try:
            cams = turntable_cameras(scene, int(frames), *size, up=up)
        except GStyleError as exc:
            self.panel.status = f"turntable: {exc}"
            return None
        out = Path(path) if path else turntable_path(self.output_dir, fmt, time.strftime("%Y%m%d_%H%M%S"))
        self.video_job = VideoJob(scene, cams, out, in_thread=self.worker_mode == "thread")
        self.panel.status = f"rendering {out.name} ({len(cams)} frames) ..."
        return out

    def _poll_video(self) -> None:
        p, job = self.panel, self.video_job
        if job is None:
            p.video_running = False
            return
        progress = job.poll()
        p.video_running = job.running
        p.video_fraction = progress.fraction
        p.video_label = f"video {progress.done}/{progress.total}"
        if not job.running:
            p.status = progress.message
            self.video_job = None
