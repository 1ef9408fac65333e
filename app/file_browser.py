"""The studio's own file browser, for desktops without a native file dialog: the model (no ImGui, no GL, no torch).

``FileBrowser`` lists one folder: its subfolders and the files whose names end in one of the accepted suffixes
(``.compressed.ply`` included), and goes up, into a subfolder, to a typed path or to a recent folder. The recent
folders (where files were last opened) are kept in the cache folder (``recent_folders.json``). The panel that draws it
is ``app/panels/file_browser.py``."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

MAX_RECENT = 8
RECENT_FILE = "recent_folders.json"


@dataclass(frozen=True)
class Entry:
    """One line of the listing: a subfolder or a file."""

    name: str
    is_dir: bool


def has_suffix(name: str, suffixes: Iterable[str]) -> bool:
    """True when ``name`` ends (case-insensitively) in one of ``suffixes`` (multi-part ones like ``.compressed.ply``
    included)."""
    lower = name.lower()
    return any(lower.endswith(s.lower()) for s in suffixes)


class FileBrowser:
    """One folder's listing, filtered by suffix, with the navigation a file dialog has."""

    def __init__(self, title: str, suffixes: Sequence[str], folder: str | os.PathLike | None = None,
                 recent: Sequence[str | os.PathLike] = (), saving: bool = False) -> None:
        self.title = title
        self.saving = saving  # a save dialog: a typed name of a file not there yet is the answer
        self.suffixes = tuple(suffixes)
        self.recent: list[Path] = [Path(p) for p in recent][:MAX_RECENT]
        self.show_all = False  # list every file, not only those with an accepted suffix
        self.show_hidden = False
        self.selected = ""  # the file name clicked last (opened with "Open")
        self.path_text = ""  # what the path field holds
        self.error = ""  # why the last action did nothing (one line)
        self.note = ""  # shown at the top: why the studio's browser opened rather than the desktop's dialog
        self.focus_path = True  # the drawing gives the path field the keyboard focus (once)
        self._entries: list[Entry] | None = None
        start = folder or (self.recent[0] if self.recent else Path.cwd())
        self.folder = Path(start).expanduser().resolve()
        if not self.go(self.folder):
            self.folder = Path.cwd().resolve()

    # ------------------------------------------------------------------ listing
    def accepts(self, name: str) -> bool:
        """True when a file of this name is listed (an accepted suffix, or "all files" on)."""
        return self.show_all or has_suffix(name, self.suffixes)

    def filter_label(self) -> str:
        """The filter, as shown under the listing: ``*.ply *.compressed.ply ...``."""
        return " ".join(f"*{s}" for s in self.suffixes)

    def entries(self) -> list[Entry]:
        """Subfolders, then accepted files, each sorted by name (hidden ones only with ``show_hidden``)."""
        if self._entries is None:
            self._entries = self._list(self.folder)
        return self._entries

    def _list(self, folder: Path) -> list[Entry]:
        dirs, files = [], []
        try:
            with os.scandir(folder) as it:
                for item in it:
                    if item.name.startswith(".") and not self.show_hidden:
                        continue
                    try:
                        is_dir = item.is_dir()
                    except OSError:  # a dangling link or a name the system will not stat
                        continue
                    if is_dir:
                        dirs.append(Entry(item.name, True))
                    elif self.accepts(item.name):
                        files.append(Entry(item.name, False))
        except OSError as exc:
            self.error = f"cannot list {folder}: {exc.strerror or exc}"
        return sorted(dirs, key=lambda e: e.name.lower()) + sorted(files, key=lambda e: e.name.lower())

    def refresh(self) -> None:
        """List the folder again (after a filter change, or files appeared)."""
        self._entries = None

    # ------------------------------------------------------------------ navigation
    def go(self, folder: str | os.PathLike) -> bool:
        """Show ``folder``; False (and ``error`` says why) when it is not a folder that can be listed."""
        target = Path(folder).expanduser()
        if not target.is_absolute():
            target = self.folder / target
        target = target.resolve()
        if not target.is_dir():
            self.error = f"not a folder: {target}"
            return False
        if not os.access(target, os.R_OK | os.X_OK):
            self.error = f"cannot list {target}: permission denied"
            return False
        self.folder, self.selected, self.error = target, "", ""
        self.path_text = ""
        self.refresh()
        return True

    def up(self) -> bool:
        """Go to the parent folder (False at the root)."""
        return self.folder.parent != self.folder and self.go(self.folder.parent)

    def enter(self, name: str) -> bool:
        """Go into the subfolder ``name``."""
        return self.go(self.folder / name)

    def select(self, name: str) -> None:
        """Mark a file of the listing (the path field shows its name)."""
        self.selected = self.path_text = name
        self.error = ""

    def submit(self, text: str | None = None) -> Path | None:
        """The path field's text (or ``text``), as Enter or "Open" takes it: a folder is shown, an existing file is
        chosen (returned, its folder remembered); anything else sets ``error``. Relative paths are in the folder."""
        text = (self.path_text if text is None else text).strip()
        if not text:
            text = self.selected
        if not text:
            self.error = "choose a file (or type its path)"
            return None
        target = Path(text).expanduser()
        target = target if target.is_absolute() else self.folder / target
        if target.is_dir():
            self.go(target)
            return None
        if self.saving:
            return self._save_target(target)
        if not target.is_file():
            self.error = f"no such file: {target}"
            return None
        return self.choose(target)

    def _save_target(self, target: Path) -> Path | None:
        """Where to save: ``target`` in a folder that exists, ending in an accepted suffix (the first one added
        when it ends in none)."""
        if not target.parent.is_dir():
            self.error = f"no such folder: {target.parent}"
            return None
        if not has_suffix(target.name, self.suffixes):
            target = target.with_name(target.name + self.suffixes[0])
        return self.choose(target)

    def choose(self, path: str | os.PathLike) -> Path:
        """``path`` is the answer: remember its folder among the recent ones and return it (absolute)."""
        chosen = Path(path).expanduser().resolve()
        self.remember(chosen.parent)
        return chosen

    def remember(self, folder: str | os.PathLike) -> None:
        """Put ``folder`` first among the recent folders."""
        self.recent = with_recent(self.recent, folder)


def with_recent(recent: Sequence[str | os.PathLike], folder: str | os.PathLike) -> list[Path]:
    """``recent`` with ``folder`` first (once), at most ``MAX_RECENT`` long."""
    folder = Path(folder).expanduser().resolve()
    return [folder] + [Path(p) for p in recent if Path(p) != folder][: MAX_RECENT - 1]


# ---------------------------------------------------------------------- recent folders on disk
def recent_folders_file() -> Path:
    """Where the recent folders are kept: ``recent_folders.json`` in the cache folder."""
    from gstyle_core.paths import cache_dir

    return cache_dir() / RECENT_FILE


def load_recent(path: str | os.PathLike) -> list[Path]:
    """The recent folders saved at ``path`` that still exist (none when the file is missing or unreadable)."""
    try:
        names = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(names, list):
        return []
    return [Path(n) for n in names if isinstance(n, str) and Path(n).is_dir()][:MAX_RECENT]


def save_recent(path: str | os.PathLike, folders: Sequence[str | os.PathLike]) -> bool:
    """Write the recent folders (atomically); False when it cannot be written (the studio goes on without)."""
    from gstyle_core.atomic import atomic_write_bytes

    data = json.dumps([str(f) for f in folders[:MAX_RECENT]], indent=1).encode("utf-8")
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(path, data)
    except OSError:
        return False
    return True
