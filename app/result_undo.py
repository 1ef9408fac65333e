"""Results on the undo stack (issue #35 item 1): before a restart, a refine, or another scene or painting replaces a
stylized result, the engine writes it (scene and summary, as an export) into the session's history folder in the
cache folder; Ctrl+Z opens it again as a result (``app/result_files.py``: its settings in the panel, nothing
running), after saving the result it replaced so that Ctrl+Shift+Z brings that one back. At most ``KEPT_RESULTS``
files are kept (the oldest go first). ``ResultUndo`` is a part of ``StudioApp``."""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gstyle_core.engine.kept_runs import history_root
from gstyle_core.engine.plan import STYLIZED_PHASES

from .edit_history import ChoiceEdit, Edit, ParamEdit, RegionEdit, ResultEdit
from .events import Events, Handlers, RunReplacing
from .export import summary_path
from .status_line import StatusLine

if TYPE_CHECKING:
    from .engine_link import EngineLink
    from .paintings import Paintings
    from .region_tool import RegionTool
    from .session import Session

KEPT_RESULTS = 12


def history_folder() -> Path:
    """This studio session's folder for replaced results (one per process)."""
    return history_root() / f"session_{os.getpid()}"


def in_history(path: str | Path) -> bool:
    """``path`` is a saved result of the undo stack (not an export of the artist's: no take)."""
    return Path(path).resolve().parent == history_folder().resolve()


class ResultUndo:
    """Undo and redo over the session's edit history: parameter steps, the region, choices and replaced results.
    Built with the status line, the events (a run about to be replaced is saved first: ``RunReplacing``), the
    session (its history, the scene and result on show), the engine link, the paintings, the region tool,
    ``open_path`` (a saved result opens as a scene: the file opening's) and ``apply_params`` (controls to the panel
    and the engine)."""

    def __init__(self, status: StatusLine, events: Events, session: Session, engine: EngineLink,
                 paintings: Paintings, region: RegionTool, *, open_path: Callable[[str], bool],
                 apply_params: Callable[[dict[str, float]], None]) -> None:
        self.status, self.session, self.engine, self.paintings, self.region = status, session, engine, paintings, region
        self.history = session.history
        self.open_path, self.apply_params = open_path, apply_params
        self._restoring = False  # an undo or redo is opening a saved result: what it replaces was saved already
        events.subscribe(RunReplacing, lambda event: self.keep_result(event.action))

    def has_result(self) -> bool:
        """An engine is running and shows stylized colours (something a restart would throw away)."""
        bridge = self.engine.bridge
        st = bridge.state if bridge is not None and bridge.alive else None
        return bool(st is not None and st.snapshot and st.snapshot.get("phase") in STYLIZED_PHASES)

    def save_result(self) -> Path | None:
        """Ask the engine to write its result into the history folder (None when there is none to save)."""
        if not self.has_result():
            return None
        folder = history_folder()
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"result_{time.strftime('%Y%m%d_%H%M%S')}_{time.monotonic_ns() % 10**6:06d}.ply"
        self.engine.bridge.export(path)
        kept = sorted(folder.glob("result_*.ply"), key=lambda p: p.stat().st_mtime)
        for old in kept[:max(0, len(kept) - KEPT_RESULTS + 1)]:
            for f in (old, summary_path(old)):
                f.unlink(missing_ok=True)
        return path

    def shown_result_file(self) -> Path | None:
        """The result file on show with no engine (opened, or by an undo or redo): an undo leaves it as it is on
        disk, so redo opens it again."""
        bridge, session = self.engine.bridge, self.session
        if session.result is None or session.loaded is None or (bridge is not None and bridge.alive):
            return None
        return Path(session.loaded.path)

    def keep_result(self, action: str) -> None:
        """Before ``action`` replaces the running result: save it and make it a step back."""
        if self._restoring:
            return
        path = self.save_result()
        if path is not None:
            self.history.record_result(ResultEdit(path, action))

    def forget_results(self) -> None:
        """Delete this session's saved results (the studio closes: its undo stack goes with it)."""
        shutil.rmtree(history_folder(), ignore_errors=True)

    def undo_or_redo(self, name: str) -> None:
        """Ctrl+Z (``name`` "undo") or Ctrl+Shift+Z / Ctrl+Y ("redo"): the step back or forward, parameters or a
        result."""
        edit = self.history.undo() if name == "undo" else self.history.redo()
        if edit is None:
            self.status.say(f"nothing to {name}")
            return
        if isinstance(edit, ParamEdit):
            self.apply_params(edit.before if name == "undo" else edit.after)
            self.status.say(f"{name}: {edit.describe()}")
            return
        if isinstance(edit, RegionEdit):
            self.region.restore(edit.before if name == "undo" else edit.after)
            self.status.say(f"{name}: {edit.describe()}")
            return
        if isinstance(edit, ChoiceEdit):
            self.undo_or_redo_choice(edit, name)
            return
        if name == "undo":
            edit.after = self.save_result() or self.shown_result_file() or edit.after  # what undo leaves, for redo
            target = edit.before
        else:
            target = edit.after
        if target is None or not self._wait_for(target):
            self.status.say(f"{name}: that result was not saved (nothing changed)")
            return
        self._open_restoring(target)
        self.status.say(f"{name}: {edit.describe()} is back" if name == "undo" else f"redo: {target.name} is back")

    # ------------------------------------------------------------------ choices that restart the engine
    def choice_state(self, kind: str) -> Any:
        """What is chosen now: the painting(s) (``painting_state``) or the quality."""
        if kind == "painting":
            return self.paintings.painting_state()
        return str(self.engine.config.get("preset") or "preview")

    def choice_step(self, kind: str, before: Any, last_step: Edit | None) -> None:
        """A choice was made (a painting opened, mixed in or removed; another quality): one undo step, unless it
        changed nothing or a result it replaced is the step already (``last_step``: the newest step before it)."""
        after = self.choice_state(kind)
        if after != before and self.history.last() is last_step and not self._restoring:
            self.history.record_result(ChoiceEdit(kind, before, after))

    def undo_or_redo_choice(self, edit: ChoiceEdit, name: str) -> None:
        """Put the choice before (undo) or after (redo) ``edit`` back; the engine restarts with it. Undo saves a
        result made after the choice first; redo opens it again instead of starting over."""
        from gstyle_core.errors import GStyleError

        if name == "undo":
            edit.result_after = self.save_result() or edit.result_after
        elif edit.result_after is not None and self._wait_for(edit.result_after):
            self._open_restoring(edit.result_after)
            self.status.say(f"redo: {edit.result_after.name} is back")
            return
        state = edit.before if name == "undo" else edit.after
        self._restoring = True
        try:
            if edit.kind == "painting":
                self.paintings.put_paintings(state)
            else:
                self.engine.set_quality(state)
            if self.engine.bridge is not None:
                self.engine.start(action=f"{name} of the {edit.kind}")
        except GStyleError as exc:
            self.status.say(f"{name}: {exc}")
            return
        finally:
            self._restoring = False
        self.status.say(f"{name}: {edit.describe()}")

    def _open_restoring(self, path: Path) -> None:
        """Open a saved result as undo and redo do: what it replaces was saved already."""
        self._restoring = True
        try:
            self.open_path(str(path))
        finally:
            self._restoring = False

    def _wait_for(self, path: Path, seconds: float = 30.0) -> bool:
        """The engine writes a saved result in the background: wait until its file and summary are there."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if path.is_file() and summary_path(path).is_file():
                return True
            if self.engine.bridge is not None:
                self.engine.bridge.poll()
            time.sleep(0.05)
        return path.is_file()

    def commands(self) -> Handlers:
        """The panel's commands this part carries out: undo and redo."""
        return {"undo": lambda _args: self.undo_or_redo("undo"), "redo": lambda _args: self.undo_or_redo("redo")}
