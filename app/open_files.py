"""Opening files in the studio: a scene (with its cameras) or a painting, dropped on the window or chosen with the
panel's buttons. The buttons open the desktop's file dialog where there is one (Windows, macOS; on Linux zenity,
kdialog, matedialog or qarma) and the studio's own file browser otherwise (``app/file_browser.py``), saying so.
``GSTYLE_FILE_DIALOG=studio`` always uses the studio's browser. ``OpenFiles`` is a part of ``StudioApp``."""

from __future__ import annotations

import os
import shutil
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import GStyleError
from gstyle_core.images import IMAGE_SUFFIXES
from gstyle_core.io import SCENE_SUFFIXES
from gstyle_core.io.sog_files import is_sog_folder
from gstyle_core.outputs import BATCH_TABLE
from gstyle_core.scene import GaussianScene

from .events import Handlers
from .export import EXPORT_SUFFIXES
from .file_browser import FileBrowser, has_suffix, load_recent, recent_folders_file, save_recent, with_recent

if TYPE_CHECKING:
    from .engine_link import EngineLink
    from .paintings import Paintings
    from .panels import PanelState
    from .result_undo import ResultUndo
    from .session import Session
    from .status_line import StatusLine
    from .studio_outputs import Outputs
    from .takes_view import TakesView

DIALOG_ENV = "GSTYLE_FILE_DIALOG"  # "studio": the studio's browser always; "auto" (default): native where there is one
DIALOG_PROGRAMS = ("zenity", "kdialog", "matedialog", "qarma")  # what portable_file_dialogs runs on Linux
NO_PROGRAM = "no file dialog program found (zenity, kdialog, matedialog or qarma; e.g. apt-get install zenity)"
QUICK_EXIT_S = 1.0  # a native dialog that ends sooner without an answer did not open (nobody cancels that fast)


@dataclass(frozen=True)
class FileKind:
    """What an open button asks for: the dialog's title, its filter's name and the accepted suffixes."""

    title: str
    filter_name: str
    suffixes: tuple[str, ...]
    style_slot: int = 0
    saving: bool = False  # a save dialog: the answer is where to write (the file may not exist yet)


FILE_KINDS = {
    "open_scene": FileKind("Open scene", "Gaussian scenes", (*SCENE_SUFFIXES, BATCH_TABLE)),  # or a batch's table
    "open_style": FileKind("Open style image", "Images", IMAGE_SUFFIXES),
    "open_style2": FileKind("Open second style image", "Images", IMAGE_SUFFIXES, style_slot=1),
    "save_as": FileKind("Save the stylized scene as", "Gaussian scenes", tuple(EXPORT_SUFFIXES.values()),
                        saving=True),
}


def native_dialog(platform: str | None = None, which: Callable[[str], str | None] | None = None,
                  env: Mapping[str, str] | None = None) -> tuple[str | None, str]:
    """(the native file dialog to use, or None; why none): Windows and macOS always have one, Linux needs a dialog
    program (``which``: ``shutil.which``); ``GSTYLE_FILE_DIALOG=studio`` asks for none."""
    env = os.environ if env is None else env
    platform = sys.platform if platform is None else platform
    which = shutil.which if which is None else which
    if env.get(DIALOG_ENV, "auto").strip().lower() == "studio":
        return None, f"{DIALOG_ENV}=studio"
    if platform.startswith(("win", "darwin")):
        return "system", ""
    found = next((p for p in DIALOG_PROGRAMS if which(p)), None)
    return (found, "") if found else (None, NO_PROGRAM)


@dataclass
class LoadedScene:
    """The scene being stylized, with the cameras that came with it (or were generated)."""

    path: str
    scene: GaussianScene
    cameras: list[Camera]
    generated_cameras: bool = False  # the cameras were made up around the scene (a bare scene file), not its own
    frame_box: tuple[Any, Any] | None = None  # a result's: its input's box, recorded in its OUT.json


def is_scene(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a scene the studio opens: a scene file's name (``SCENE_SUFFIXES``) or a SOG folder."""
    return has_suffix(Path(path).name, SCENE_SUFFIXES) or is_sog_folder(path)


def load_scene_with_cameras(scene_path: str | None, cameras_path: str | None) -> LoadedScene:
    """Load a scene file (default: the bundled demo) and its cameras (given, else generated)."""
    from gstyle_core.assets import DEMO_SCENE
    from gstyle_core.cameras.recorded import record_box
    from gstyle_core.scene_images import load_scene_and_cameras

    path = Path(scene_path) if scene_path else DEMO_SCENE
    if not path.exists():
        what = "scene file" if scene_path else "bundled demo scene"
        raise GStyleError(f"{what} not found: {path}")
    scene, _report, cams = load_scene_and_cameras(scene_path, cameras_path)
    return LoadedScene(str(scene_path or DEMO_SCENE), scene, list(cams.cameras), cams.source.startswith("generated"),
                       record_box(getattr(cams, "generated", None)))


class OpenFiles:
    """Opening files: owns the native dialog open (``dialog``: kind, dialog, program, start time), the kind the
    studio's browser was opened for (the browser itself is the panel's ``browser``) and where the recent folders are
    kept. Built with the panel, the status line, the session (the scene to show), the engine link (stopped for a
    result, restarted for anything else), the paintings, the undo (a painting opened is a step), the takes (a batch
    opens as takes) and the outputs (Save As, and where it starts)."""

    def __init__(self, panel: PanelState, status: StatusLine, session: Session, engine: EngineLink,
                 paintings: Paintings, undo: ResultUndo, takes: TakesView, outputs: Outputs) -> None:
        self.panel, self.status, self.session, self.engine = panel, status, session, engine
        self.paintings, self.undo, self.takes, self.outputs = paintings, undo, takes, outputs
        self.recent_file: Path | None = None  # where the recent folders are kept (None: the cache folder's file)
        self.dialog: tuple[str, Any, str, float] | None = None  # a native file dialog and what it is for
        self._browser_kind = "open_scene"

    def on_drop(self, paths: Any) -> None:
        """glfw drop callback: open the first dropped file (a scene or a style image); more files are ignored."""
        paths = list(paths)
        if paths:
            self.open_path(paths[0])
            if len(paths) > 1:
                self.status.add(f" ({len(paths) - 1} more dropped file(s) ignored)")

    def open_path(self, path: str, style_slot: int = 0, record: bool = True) -> bool:
        """Open a dropped or chosen file: a scene (.ply/.compressed.ply/.splat/.spz/.sog, a SOG folder or its
        meta.json), a style image (``style_slot``
        1: as the second painting of a mix; ``record``: the choice is an undo step), or a ``gstyle batch`` folder or
        its batch.csv (its jobs as takes). True when it opened; the status line (and the terminal) says what
        happened either way."""
        name = Path(path).name
        if style_slot == 0 and (name == BATCH_TABLE or (Path(path) / BATCH_TABLE).is_file()):
            folder = Path(path).parent if name == BATCH_TABLE else Path(path)
            opened = self.takes.open_batch(folder)
            if opened:
                self._remember_folder(folder)
            return opened
        painting_before = self.paintings.painting_state() if record and has_suffix(name, IMAGE_SUFFIXES) else None
        last_step = self.session.history.last()
        try:
            if is_scene(path) and style_slot == 0:
                self.session.set_scene(load_scene_with_cameras(path, None))
                self.status.tell(f"opened {name} ({self.panel.gaussians:,} Gaussians)")
            elif has_suffix(name, IMAGE_SUFFIXES):
                self.paintings.set_style(path, style_slot)
                self.status.tell(f"opened {name} as the {'second ' if style_slot else ''}style")
            else:
                self.status.tell(f"not a scene or image: {name}")
                return False
        except GStyleError as exc:
            self.status.tell(f"could not open {name}: {exc}")
            return False
        self._remember_folder(Path(path).parent)
        result = self.session.result
        if result is not None and style_slot == 0 and is_scene(path):
            self.engine.stop()  # a result is shown as it is; Stylize again / Restart from the original start one
            self.paintings.show_result(result)
            self.status.tell(f"{result.line}; nothing started")
        elif self.engine.bridge is not None:
            self.engine.start(action=f"opening {name}")
        if painting_before is not None:
            self.undo.choice_step("painting", painting_before, last_step)
        return True

    # ------------------------------------------------------------------ recent folders
    def _recent_file(self) -> Path:
        return self.recent_file if self.recent_file is not None else recent_folders_file()

    def _recent_folders(self) -> list[Path]:
        return load_recent(self._recent_file())

    def _remember_folder(self, folder: Path) -> None:
        save_recent(self._recent_file(), with_recent(self._recent_folders(), folder))

    # ------------------------------------------------------------------ commands
    def commands(self) -> Handlers:
        """The panel's commands this part carries out: open buttons (and Save As), the studio browser's answer or
        cancel, and "use the studio's browser" instead of a native dialog."""
        opens: Handlers = {
            kind: (lambda _args, kind=kind: self._open_dialog(kind)) for kind in FILE_KINDS}
        return {**opens, "browser_open": lambda args: self._browser_answer(str(args["path"])),
                "browser_cancel": lambda _args: self._cancel_browser(),
                "use_browser": lambda _args: self._use_browser()}

    def _cancel_browser(self) -> None:
        self.panel.browser = None
        self.status.tell("no file chosen")

    def _use_browser(self) -> None:
        kind = self.dialog[0] if self.dialog is not None else self._browser_kind
        self._drop_native_dialog()
        self._open_browser(kind, "")

    def _open_dialog(self, kind: str) -> None:
        """The native dialog where there is one, else the studio's browser (the status line says why)."""
        program, why_not = native_dialog()
        if program is not None:
            try:
                self._open_native(kind, program)
                return
            except Exception as exc:  # noqa: BLE001 - an ImportError or the dialog failing to start: fall back
                why_not = f"the {program} file dialog failed ({type(exc).__name__}: {exc})"
        self._open_browser(kind, why_not)

    def _open_native(self, kind: str, program: str) -> None:
        from imgui_bundle import portable_file_dialogs as pfd

        spec = FILE_KINDS[kind]
        recent = self._recent_folders()
        start = f"{recent[0]}{os.sep}" if recent else ""
        patterns = " ".join(f"*{s}" for s in spec.suffixes)
        self._drop_native_dialog()
        if spec.saving:
            start = str(self.outputs.export_folder() / "stylized.ply")
            dialog = pfd.save_file(spec.title, start, [spec.filter_name, patterns])
        else:
            dialog = pfd.open_file(spec.title, start, [spec.filter_name, patterns])
        self.dialog = (kind, dialog, program, time.monotonic())
        self.panel.browser = None
        self.panel.dialog_note = f"Waiting for the {program} file dialog ({spec.title})."
        self.status.tell(f"{spec.title}: choose a file in the {program} file dialog")

    def _drop_native_dialog(self) -> None:
        if self.dialog is not None:
            try:
                self.dialog[1].kill()
            except Exception:  # noqa: BLE001 - it may have ended already
                pass
        self.dialog = None
        self.panel.dialog_note = ""

    def _open_browser(self, kind: str, why_not_native: str) -> None:
        spec = FILE_KINDS[kind]
        self._browser_kind = kind
        folder = self.outputs.export_folder() if spec.saving else None
        browser = FileBrowser(spec.title, spec.suffixes, folder=folder if folder and folder.is_dir() else None,
                              recent=self._recent_folders(), saving=spec.saving)
        browser.note = f"Not the desktop's file dialog: {why_not_native}." if why_not_native else ""
        self.panel.browser = browser
        reason = f"{why_not_native}; " if why_not_native else ""
        what = "type a file name or choose a file" if spec.saving else "choose a file"
        self.status.tell(f"{reason}{spec.title}: {what} in the studio's file browser")

    def _browser_answer(self, path: str) -> None:
        """The studio's browser chose ``path``: open it; on failure the browser stays open and shows why."""
        browser = self.panel.browser
        spec = FILE_KINDS[self._browser_kind]
        if spec.saving:
            self.panel.browser = None
            self.outputs.save_as(path)
        elif self.open_path(path, style_slot=spec.style_slot):
            self.panel.browser = None
        elif browser is not None:
            browser.error = self.status.text

    def poll_dialog(self) -> None:
        """A native dialog's answer, once it is ready: open the file; a dialog that ended at once without one did not
        open, so the studio's browser takes over."""
        if self.dialog is None or not self.dialog[1].ready(0):
            return
        kind, dialog, program, started = self.dialog
        self.dialog = None
        self.panel.dialog_note = ""
        answer = dialog.result()
        chosen = ([answer] if answer else []) if isinstance(answer, str) else list(answer or [])[:1]
        for path in chosen:
            if FILE_KINDS[kind].saving:
                self.outputs.save_as(path)
            else:
                self.open_path(path, style_slot=FILE_KINDS[kind].style_slot)
        if not chosen and time.monotonic() - started < QUICK_EXIT_S:
            self._open_browser(kind, f"the {program} file dialog did not open")
        elif not chosen:
            self.status.tell("no file chosen")
