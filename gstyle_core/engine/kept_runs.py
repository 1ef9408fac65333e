"""A saved result keeps its run (issue #35 item 3: *Continue* / *Refine* on a reopened result).

A PLY holds only the stylized scene: the engine's state (the ground-truth colours of the split Gaussians, the
optimisers, the content targets) is not in it. So whenever the studio's engine writes a result (Save, Save As, a
result kept for undo) and when ``gstyle stylize`` has written OUT.ply, the engine's checkpoint is saved for it
(``engine/checkpoint.py``'s format, in the cache folder; beside the file in the session's history folder for undo's
results) with a small note: the digest of the file written and the engine config it was built from. Reopened later,
a result whose file still has that digest and whose original scene and paintings are found can be continued: the
engine is rebuilt on the original from the same inputs and loads that state, so the run is where it ended (Refine,
the controls and keep colours go on from it). At most ``KEPT_STATES`` states and ``KEPT_BYTES`` are kept in the
cache folder (the oldest go first).
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

from gstyle_core.atomic import atomic_write_text
from gstyle_core.paths import cache_dir

KEPT_STATES = 24
KEPT_BYTES = 2 << 30  # a state is about 2.5x its PLY (measured: 39 MB beside a 16 MB PLY of 63k Gaussians)
NOTE_SUFFIX = ".json"


def results_folder() -> Path:
    """``cache_dir()/results``: the states of the artist's saved results."""
    return cache_dir() / "results"


def history_root() -> Path:
    """``cache_dir()/history``: the studio sessions' folders of results kept for undo (one per session)."""
    return cache_dir() / "history"


def result_state_path(result: str | Path) -> Path:
    """Where the run of the result file ``result`` is kept: beside it for undo's results (they go with the session's
    history folder), else in ``results_folder()`` under a name keyed by the file's absolute path."""
    path = Path(result).expanduser().resolve()
    if path.parent.parent == history_root().resolve():  # any session's (the worker has its own pid)
        return path.parent / f"{path.name}.state.ckpt"
    key = hashlib.blake2b(str(path).encode("utf-8", "surrogateescape"), digest_size=8).hexdigest()
    stem = "".join(ch if ch.isalnum() or ch in "._-" else "_" for ch in path.stem)[:40] or "result"
    return results_folder() / f"{stem}-{key}.ckpt"


def note_path(state: Path) -> Path:
    """The small JSON note beside a state (read when a result opens, without loading the state)."""
    return state.with_name(state.name + NOTE_SUFFIX)


def file_digest(path: str | Path) -> str:
    """blake2b of a file's bytes (a result changed by another tool no longer matches its state)."""
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def jsonable_config(config: dict[str, Any]) -> dict[str, Any]:
    """The parts of an engine config a note keeps: paths, names, numbers and lists of them (a rectangle
    selection's mask stays in the state's own meta)."""
    def plain(value: Any) -> bool:
        if isinstance(value, (list, tuple)):
            return all(plain(v) for v in value)
        return value is None or isinstance(value, (str, int, float, bool))

    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in config.items() if plain(v)}


def save_result_state(result: str | Path, state: dict[str, Any], meta: dict[str, Any]) -> Path:
    """Keep ``state`` (``engine.state_dict()``) as the run of the result file just written at ``result``; ``meta``
    as a checkpoint's (it must hold ``config``, the engine config it was built from). Returns the state's path."""
    from gstyle_core.engine.checkpoint import save_checkpoint

    path = result_state_path(result)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_checkpoint(path, state, {**meta, "kind": "result", "result": str(Path(result).resolve())})
    config = meta.get("config") or {}
    _write_note(path, result, {"config": jsonable_config(config), "selection": config.get("selection") is not None})
    return path


def _write_note(state: Path, result: str | Path, fields: dict[str, Any]) -> None:
    """The note beside ``state`` (just written for the file ``result``): ``fields`` with the file and its digest;
    then the cache folder's states pruned."""
    note = {**fields, "result": str(Path(result).resolve()), "digest": file_digest(result), "saved": time.time()}
    atomic_write_text(note_path(state), json.dumps(note, indent=2))
    if state.parent == results_folder():
        prune(state.parent)


def prune(folder: Path, keep: int = KEPT_STATES, budget: int = KEPT_BYTES) -> None:
    """Keep the newest states (and notes) in ``folder``: at most ``keep`` of them and ``budget`` bytes (the newest
    stays whatever its size); delete the rest."""
    states = sorted(folder.glob("*.ckpt"), key=lambda p: p.stat().st_mtime, reverse=True)
    total = 0
    for i, state in enumerate(states):
        total += state.stat().st_size
        if i >= keep or (i > 0 and total > budget):
            state.unlink(missing_ok=True)
            note_path(state).unlink(missing_ok=True)


def find_result_state(result: str | Path) -> tuple[Path, dict[str, Any]] | None:
    """The kept run of ``result`` and its note, when both are there and the file is still the one written with it;
    else None (the result opens all the same, with nothing to continue)."""
    path = result_state_path(result)
    try:
        note = json.loads(note_path(path).read_text())
        if path.is_file() and isinstance(note, dict) and note.get("digest") == file_digest(result):
            return path, note
    except (OSError, ValueError):
        pass
    return None


def copy_result_state(source: str | Path, result: str | Path) -> Path | None:
    """The run kept with ``source`` kept with ``result`` too (the same result saved under another name); None when
    ``source`` has none."""
    import shutil

    kept = find_result_state(source)
    if kept is None:
        return None
    state, note = kept
    path = result_state_path(result)
    path.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(state, path)
    _write_note(path, result, note)
    return path
