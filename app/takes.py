"""Takes: the studio's last few exports, kept as named snapshots to switch between and compare with the current run.

A take is an exported file (.ply, .spz, .compressed.ply or .sog) with a name the artist can change. The shelf keeps the
newest ``limit`` of them and remembers them in ``takes.json`` in the output folder, so a studio opened again on the
same folder finds them (entries whose file is gone are dropped). Forgetting a take never deletes its file. No GL
here: the studio loads a take's scene (``load``) into a renderer of its own.

A ``gstyle batch`` folder (its ``batch.csv``) opens as takes too (``add_batch``): each finished job is one, named
``SCENE after PAINTING`` with its settings line; these stay on the shelf until forgotten (the export limit does not
push them off).
"""

from __future__ import annotations

import csv
import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from gstyle_core.atomic import atomic_write_text
from gstyle_core.errors import GStyleError
from gstyle_core.outputs import BATCH_TABLE, companion, output_base
from gstyle_core.scene import GaussianScene

TAKES_FILE = "takes.json"
DEFAULT_LIMIT = 5
MAX_NAME = 40


@dataclass
class Take:
    """One export: its ``name`` (shown in the panel), file ``path``, Gaussian count and when it was written."""

    name: str
    path: str
    gaussians: int
    created: float
    view_key: str = ""  # what the view showed when it was exported (``StudioApp.view_key``): T skips a take equal to it
    settings: str = ""  # one line: the run's preset, widths and the controls set (``settings_line``)
    batch: str = ""  # the batch folder it came from ("" for an export)
    scene: str = ""  # a batch job's input scene (the studio opens a take of another scene as its scene)

    @property
    def label(self) -> str:
        """``name (N Gaussians, HH:MM)`` for lists."""
        return f"{self.name} ({self.gaussians:,} Gaussians, {time.strftime('%H:%M', time.localtime(self.created))})"


SHOWN_CONTROLS = (("lambda_nnfm", "NNFM"), ("lambda_content", "content"), ("strength", "strength"),
                  ("style_scale", "stroke"))


def widths_text(settings: dict) -> str:
    """A summary's widths, coarse to fine: ``256 -> 512 px`` ("" when it names none)."""
    widths = [w for w in (settings.get("working_width"), *(settings.get("refine_widths") or [])) if w]
    return " -> ".join(map(str, widths)) + " px" if widths else ""


def settings_line(summary: dict) -> str:
    """An export summary's settings in one line: ``preview, 256 -> 512 px; NNFM 200, content 0.05, strength 1,
    stroke 1; keep colours; palette match 0.5`` (the palette match when below 1)."""
    settings = summary.get("settings") if isinstance(summary.get("settings"), dict) else {}
    params = summary.get("params") if isinstance(summary.get("params"), dict) else {}
    head = ", ".join(x for x in (str(settings.get("preset") or ""), widths_text(settings)) if x)
    controls = ", ".join(f"{label} {float(params[key]):g}" for key, label in SHOWN_CONTROLS
                         if isinstance(params.get(key), (int, float)))
    switches = "; keep colours" if params.get("keep_colours") else ""
    palette = params.get("palette_match")
    if isinstance(palette, (int, float)) and palette != 1.0:  # below the method's full final colour match
        switches += f"; palette match {float(palette):g}"
    return "; ".join(x for x in (head, controls) if x) + switches


class TakeShelf:
    """The newest ``limit`` exports of an output folder, newest first, remembered in its ``takes.json``."""

    def __init__(self, folder: str | Path, limit: int = DEFAULT_LIMIT) -> None:
        self.folder = Path(os.path.abspath(folder))  # (takes.json's paths are absolute: the studio may start elsewhere)
        self.limit = max(1, int(limit))
        self.takes: list[Take] = self._read()
        self.write_error: str | None = None
        self._counter = len(self.takes)

    def _read(self) -> list[Take]:
        """The remembered takes whose files still exist (an unreadable list is ignored: takes are a convenience)."""
        try:
            entries = json.loads((self.folder / TAKES_FILE).read_text())
            takes = [Take(str(e["name"]), os.path.abspath(str(e["path"])), int(e["gaussians"]), float(e["created"]),
                          str(e.get("view_key", "")), str(e.get("settings", "")), str(e.get("batch", "")),
                          str(e.get("scene", "")))
                     for e in entries]
        except (OSError, ValueError, TypeError, KeyError):
            return []
        return self._trimmed([t for t in takes if Path(t.path).is_file()])

    def _trimmed(self, takes: list[Take]) -> list[Take]:
        """``takes`` without the exports beyond the newest ``limit`` (a batch's takes all stay)."""
        exports = [t for t in takes if not t.batch][: self.limit]
        return [t for t in takes if t.batch or t in exports]

    def _write(self) -> None:
        """Save the list (atomically: the old ``takes.json`` stays whole); a failure (a read-only folder, a full
        disk) is kept as one line for the panel (``pop_write_error``): the takes still work for this session."""
        try:
            atomic_write_text(self.folder / TAKES_FILE, json.dumps([asdict(t) for t in self.takes], indent=2))
        except OSError as exc:  # OutputWriteError: "cannot write .../takes.json: <cause>"
            self.write_error = " ".join(str(exc).split())
        else:
            self.write_error = None

    def pop_write_error(self) -> str | None:
        """The last failure to save ``takes.json`` not yet shown (then forgotten)."""
        error, self.write_error = self.write_error, None
        return error

    def add(self, path: str | Path, gaussians: int, name: str | None = None, view_key: str = "",
            settings: str = "") -> Take:
        """Shelve an export (newest first; the oldest beyond ``limit`` is forgotten, its file kept); ``view_key``:
        what the view showed when it was written; ``settings``: its one-line settings."""
        self._counter += 1
        take = Take(name or f"take {self._counter}", os.path.abspath(path), int(gaussians), time.time(), view_key,
                    settings)
        self.takes = self._trimmed([take] + [t for t in self.takes if t.path != take.path])
        self._write()
        return take

    def add_batch(self, folder: str | Path) -> list[Take]:
        """Shelve every finished job of the ``gstyle batch`` folder ``folder`` (in the batch's order, first on top,
        before the other takes); ``GStyleError`` when its ``batch.csv`` cannot be read."""
        new = batch_takes(folder)
        paths = {t.path for t in new}
        self.takes = new + [t for t in self.takes if t.path not in paths]
        self._write()
        return new

    def rename(self, index: int, name: str) -> None:
        """Give take ``index`` a new name (trimmed; an empty name keeps the old one)."""
        name = " ".join(str(name).split())[:MAX_NAME]
        if name and 0 <= index < len(self.takes):
            self.takes[index].name = name
            self._write()

    def forget(self, index: int) -> Take | None:
        """Take ``index`` off the shelf (its file stays on disk)."""
        if not 0 <= index < len(self.takes):
            return None
        take = self.takes.pop(index)
        self._write()
        return take

    def load(self, index: int) -> GaussianScene:
        """The scene of take ``index`` as its file holds it (``SceneFormatError`` / ``OSError`` when it cannot be
        read any more)."""
        from gstyle_core.io import load_scene

        scene, _report = load_scene(self.takes[index].path)
        return scene


def batch_takes(folder: str | Path) -> list[Take]:
    """A take per finished job in ``folder``'s ``batch.csv`` whose scene file is there: ``SCENE after PAINTING``
    (``, RUN`` with a plan), its Gaussian count and settings line from its OUT.json. ``GStyleError``: no table."""
    folder = Path(os.path.abspath(folder))  # its takes' paths absolute, as every take's
    table = folder / BATCH_TABLE
    try:
        with open(table, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else " ".join(str(exc).split())
        raise GStyleError(f"cannot read {table}: {why}") from None
    if rows and not {"scene", "painting", "status", "out"} <= set(rows[0]):
        raise GStyleError(f"{table} is not a gstyle batch table (no scene, painting, status and out columns)")
    takes = []
    for row in rows:
        path = folder / Path(row["out"] or "").name  # the folder opened, wherever the batch was run from
        if row["status"] not in ("done", "done already") or not path.is_file():
            continue
        try:
            summary = json.loads(companion(path, ".json").read_text(encoding="utf-8"))
            settings = summary["settings"]
            weights = {f"lambda_{k}": v for k, v in (settings.get("weights") or {}).items()}
            gaussians, line = int(summary["gaussians_after"]), settings_line({"settings": settings,
                                                                              "params": {**weights, **settings}})
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            gaussians, line = 0, ""
        name = f"{output_base(Path(row['scene']).name).name} after {Path(row['painting']).stem}"
        name += f", {row['run']}" if row.get("run") else ""
        takes.append(Take(name[:MAX_NAME], str(path), gaussians, path.stat().st_mtime, settings=line,
                          batch=str(folder), scene=row["scene"] or ""))
    return takes
