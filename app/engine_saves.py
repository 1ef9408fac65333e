"""The engine worker's saved runs: the session checkpoint, written on its own while the run steps (``autosave``:
a killed worker loses about half a minute of steps) and when the studio closes, the run kept with an exported
result, resuming from either, and handing a run over to another device (``move_to``). ``RunSaves`` is a part of
``app.engine_host.EngineHost`` (its ``saves``), built with the host: it reads the host's engine, config, params and
fingerprint, speaks through its ``send`` and builds engines with its ``build``; it owns the hand-over."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gstyle_core.crash import log_crash
from gstyle_core.engine.save_pacing import AUTOSAVE_SECONDS, SavePacing
from gstyle_core.errors import one_line_error

AUTOSAVE_ENV = "GSTYLE_AUTOSAVE_SECONDS"  # the seconds between the worker's own saves (tests shorten it)

if TYPE_CHECKING:
    from .engine_host import EngineHost


class RunSaves:
    """An ``EngineHost``'s checkpoints, kept runs, resumes and device hand-overs."""

    def __init__(self, host: EngineHost) -> None:
        self.host = host
        self.handover: str | None = None  # the run's state saved by the last move to another device (``move_to``)
        self._handover_folder: tempfile.TemporaryDirectory | None = None
        self.pacing = SavePacing(float(os.environ.get(AUTOSAVE_ENV) or AUTOSAVE_SECONDS))
        self._paced_engine: Any = None  # the engine the pacing's clock started for (a new one starts it again)

    def drop_handover(self) -> None:
        """A restart starts from its inputs: no run to move on from."""
        self.handover = None

    def saved_meta(self) -> dict[str, Any]:
        """What a checkpoint of this engine says of its inputs: the config and params it was built from (to build
        it again), its fingerprint, the params now."""
        host = self.host
        return {"scene": host.config.get("scene"), "style": host.config.get("style"), "config": dict(host.config),
                "fingerprint": host.fingerprint, "build_params": dict(host.build_params), "params": dict(host.params),
                "level_weights": {k: list(v) for k, v in host.level_weights.items()}}

    def save_state(self, path: str) -> None:
        """Write the engine's state with ``saved_meta`` as a studio checkpoint at ``path`` (raises what the save
        raised)."""
        from gstyle_core.engine.checkpoint import save_checkpoint

        save_checkpoint(path, self.host.engine.state_dict(), {"kind": "studio", **self.saved_meta()})

    def keep_run(self, written: str) -> None:
        """Keep the engine's state with the result just written (``gstyle_core/engine/kept_runs.py``), so that the
        result can be continued when it is reopened; a failure only says so (the result itself was written)."""
        engine = self.host.engine
        if not hasattr(engine, "state_dict") or not hasattr(engine, "input_scene"):
            return
        try:
            from gstyle_core.engine.kept_runs import save_result_state

            save_result_state(written, engine.state_dict(), self.saved_meta())
        except Exception as exc:  # noqa: BLE001
            self.host.send("error", f"saved, but its run was not kept (it cannot be continued): {one_line_error(exc)}; "
                                    f"{log_crash(exc, 'studio-keep-run', [f'keeping the run of {written}'])}")

    def autosave(self) -> None:
        """After a step: the session checkpoint when it is due (``SavePacing``: every 30 s of stepping, further apart
        when a save costs over 3 % of the time) and once more when the run is done; says ``autosaved`` with the
        step it holds and what the save took. The first step of a new engine starts the clock."""
        host = self.host
        if host.engine is None or not host.checkpoint_path or not hasattr(host.engine, "state_dict"):
            return
        if host.engine is not self._paced_engine:
            self._paced_engine = host.engine
            self.pacing.start()
        if not (self.pacing.due() or host.done):
            return
        started = time.perf_counter()
        try:
            self.save_state(host.checkpoint_path)
        except Exception as exc:  # noqa: BLE001 - a full or read-only cache: said once a save, the run goes on
            self.pacing.saved(time.perf_counter() - started)
            host.send("error", f"saving the session: {one_line_error(exc)}; the run goes on unsaved")
            return
        seconds = time.perf_counter() - started
        self.pacing.saved(seconds)
        host.send("autosaved", {"path": str(host.checkpoint_path), "step": host.steps_done(), "seconds": seconds})

    def checkpoint(self) -> None:
        """Save the engine's state, the fingerprint of its inputs and the slider values (cache folder)."""
        host = self.host
        if host.engine is None or not host.checkpoint_path:
            return
        try:
            self.save_state(host.checkpoint_path)
            host.send("checkpoint", str(host.checkpoint_path))
        except Exception as exc:  # noqa: BLE001
            host.send("error", f"checkpoint: {one_line_error(exc)}")

    def read(self, path: str) -> tuple[dict[str, Any], dict[str, Any]] | None:
        """The checkpoint at ``path`` (state, meta), or None after saying in one line why it cannot be read."""
        try:
            from gstyle_core.engine.checkpoint import read_checkpoint

            return read_checkpoint(path)
        except Exception as exc:  # noqa: BLE001
            self.host.send("error", f"resume: {one_line_error(exc)}; starting afresh")
            return None

    @staticmethod
    def saved_inputs(meta: dict[str, Any], params: dict[str, float], config: dict[str, Any]) -> tuple[
            dict[str, float], dict[str, tuple[float, float]], dict[str, Any]]:
        """What the host takes on before building an engine that will load a checkpoint (from ``params`` and
        ``config``, its own): the params it was built with (so the settings match its fingerprint), the weights its
        Refine levels set (``drop_level_weights`` after a later restart) and, for a result's run, the config it was
        built from (a region's mask included)."""
        if isinstance(meta.get("build_params"), dict):
            params = dict(meta["build_params"])
        levels = meta.get("level_weights")
        level_weights = {str(k): (float(v[0]), float(v[1])) for k, v in levels.items()} \
            if isinstance(levels, dict) else {}
        if meta.get("kind") == "result" and isinstance(meta.get("config"), dict):
            config = dict(meta["config"])
        return params, level_weights, config

    def load_checkpoint(self, path: str, saved: tuple[dict[str, Any], dict[str, Any]]) -> None:
        """Continue from ``saved`` (``read(path)``) when it was made for the same inputs; otherwise say why in one
        line and go on with the fresh engine."""
        host = self.host
        try:
            from gstyle_core.engine.checkpoint import check_fingerprint

            state, meta = saved
            check_fingerprint(path, meta, host.fingerprint)
            host.engine.load_state_dict(state)
        except Exception as exc:  # noqa: BLE001 - a bad checkpoint is reported; the fresh engine carries on
            host.send("error", f"resume: {one_line_error(exc)}; starting afresh; "
                          f"{log_crash(exc, 'studio-resume', [f'resuming from {path}'])}")
            return
        step = getattr(host.engine, "global_step", state.get("global_step", state.get("steps")))
        host.send("resumed", {"checkpoint": str(path), "step": step})
        if meta.get("params"):
            host.set_params(dict(meta["params"]))

    def move_to(self, config: dict[str, Any]) -> None:
        """Build the engine again from ``config`` (on the device it names) and go on from the run's state: the
        engine's now (a step that failed keeps none of its work: the colours, the geometry and their moments are as
        that step found them; only a refit's shuffle has moved past the failed step's view), or, with no engine (it
        could not be built on the device moved to), the state handed over last. The hand-over is kept until a
        restart, so a move that fails loses nothing: moving back goes on from it. Without either it starts afresh
        and says so."""
        if self.host.engine is not None:
            self.hand_over()
        self.host.build(config, resume_from=self.handover)

    def hand_over(self) -> None:
        """Save the engine's state for the engine that takes over (``handover``); a failure says so in one line and
        leaves none (the next engine starts afresh)."""
        if self._handover_folder is None:
            self._handover_folder = tempfile.TemporaryDirectory(prefix="gstyle-handover-")
        path = str(Path(self._handover_folder.name) / "handover.ckpt")
        self.handover = None
        try:
            self.save_state(path)
        except Exception as exc:  # noqa: BLE001 - e.g. a device that cannot give its tensors back, a full disk
            self.host.send("error", f"the run could not be handed over ({one_line_error(exc)}); starting afresh; "
                                    f"{log_crash(exc, 'studio-handover', ['handing the run over'])}")
            return
        self.handover = path
