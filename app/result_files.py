"""A scene file this project wrote (a stylized result) opens as a result (issue #35 item 3): recognised by the JSON
summary beside it (``gstyle stylize``'s OUT.json, or the studio's export summary), with its settings, the original
scene it came from when that file is found, and a one-line description. A scene without such a summary is a foreign
scene and opens as before (the engine starts on it)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gstyle_core.engine.kept_runs import find_result_state
from gstyle_core.engine.settings import StylizeSettings, refined_level_weights, ui_params

from .export import summary_path
from .takes import widths_text


@dataclass
class ResultInfo:
    """What the summary beside a result says: its panel values, where the original scene is, one line."""

    summary: Path
    params: dict[str, float] = field(default_factory=dict)
    source: Path | None = None  # the original scene, when that file exists
    source_named: str = ""  # the original as the summary names it (shown when it is not found)
    line: str = ""
    preset: str = ""
    styles: list[Path] = field(default_factory=list)  # its paintings whose files are found
    state: Path | None = None  # the run kept with it (``engine/kept_runs.py``) while the file is still as written
    state_config: dict[str, Any] = field(default_factory=dict)  # the engine config that run was built from
    levels: list[int] = field(default_factory=list)  # its widths, coarse to fine (the last: the result's width)
    level_weights: dict[str, tuple[float, float]] = field(default_factory=dict)  # controls a Refine's level set:
    # (the level's value, the preset's: what a restart at the preset goes back to; ``refined_level_weights``)


def read_result(scene_path: str | Path) -> ResultInfo | None:
    """The result ``scene_path`` is, or None for a foreign scene (no readable summary with settings beside it)."""
    path = Path(scene_path)
    summary = summary_path(path)
    try:
        data = json.loads(summary.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not isinstance(data.get("settings"), dict):
        return None
    info = ResultInfo(summary)
    params = data.get("params")
    if isinstance(params, dict):
        info.params = {k: float(v) for k, v in params.items() if isinstance(v, (int, float))}
    else:
        try:
            info.params = ui_params(StylizeSettings.from_dict(data["settings"]))
        except ValueError:
            info.params = {}
    named = data.get("source_scene") or data.get("scene") or ""
    if named and Path(named).resolve() != path.resolve():
        info.source_named = str(named)
        info.source = _found(Path(named), summary.parent)
    info.line = _describe(data, path)
    info.preset = str(data["settings"].get("preset") or "")
    info.levels = level_widths(data["settings"])
    try:
        info.level_weights = refined_level_weights(StylizeSettings.from_dict(data["settings"]))
    except (ValueError, TypeError):
        info.level_weights = {}
    for entry in data.get("styles") or []:
        found = _found(Path(str(entry.get("path", ""))), summary.parent) if isinstance(entry, dict) else None
        if found is not None:
            info.styles.append(found)
    kept = find_result_state(path)
    if kept is not None:
        info.state, note = kept
        info.state_config = dict(note.get("config") or {})
    return info


def level_widths(settings: dict) -> list[int]:
    """A summary's widths, coarse to fine: its working width and its finer levels' (those it names)."""
    widths = [settings.get("working_width"), *(settings.get("refine_widths") or [])]
    return [int(w) for w in widths if isinstance(w, (int, float)) and w > 0]


def _found(named: Path, beside: Path) -> Path | None:
    """``named`` as it is (absolute, or relative to where the studio runs), else relative to the summary's folder."""
    for candidate in (named, beside / named):
        if candidate.is_file():
            return candidate.resolve()
    return None


def _describe(data: dict, path: Path) -> str:
    """``preset balanced, 256 -> 512 px, after starry_night.jpg, 215,468 Gaussians``."""
    settings = data["settings"]
    styles = data.get("styles") or [data.get("style")]
    names = [Path(str(s.get("path", "")) if isinstance(s, dict) else str(s or "")).name for s in styles]
    count = data.get("gaussians_after", data.get("gaussians"))
    parts = [x for x in (f"preset {settings.get('preset', '?')}", widths_text(settings)) if x]
    if any(names):
        parts.append("after " + " + ".join(n for n in names if n))
    if isinstance(count, int):
        parts.append(f"{count:,} Gaussians")
    return f"{path.name}: a stylized result ({', '.join(parts)})"
