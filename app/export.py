"""The studio's exports: the stylized scene as .ply, .spz, .compressed.ply or .sog (PlayCanvas SOG) with a JSON
summary beside it (written by the engine worker, which holds the engine)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .snapshot import scene_from_snapshot

EXPORT_SUFFIXES = {"ply": ".ply", "spz": ".spz", "compressed-ply": ".compressed.ply", "sog": ".sog"}  # the exports
EXPORT_FORMATS = tuple(EXPORT_SUFFIXES)  # (the web formats for web viewers)


def export_engine(engine: Any, path: Path, last_report: dict[str, Any] | None, params: dict[str, float],
                  style: str | list[str] | None = None, source_scene: str | None = None) -> str:
    """Save the stylized scene as .ply, .spz, .compressed.ply or .sog (``gstyle_core.io.save_scene``) and a JSON summary
    beside it (``summary_path``; ``style``: the engine's painting path(s), named there with their weights;
    ``source_scene``: the scene it was stylized from, so the result reopens with a way back to it). Both appear or
    neither (``OutputGroup``): a failed write (``OutputWriteError``, one line) leaves no take behind."""
    fmt = _export_format(path)
    scene = engine.stylized_scene() if hasattr(engine, "stylized_scene") else scene_from_snapshot(engine.snapshot())
    source = str(Path(source_scene).resolve()) if source_scene else None
    summary = {"scene": str(path), "source_scene": source, "gaussians": scene.count,
               "styles": style_entries(engine, style),
               "report": last_report, "params": params,
               "decisions": getattr(engine, "decisions", None),
               "settings": engine.settings.to_dict() if hasattr(getattr(engine, "settings", None), "to_dict")
               else None}
    return _write_export(path, fmt, scene, summary)


def export_shown_result(scene: Any, summary_file: str | Path, path: Path) -> str:
    """Save a result the studio shows with no engine running (reopened, or brought back by Ctrl+Z) under ``path``:
    the scene as it was opened, in the format ``path``'s suffix names, and its summary copied beside it (settings,
    paintings and original kept; ``scene`` and ``gaussians`` say what was written). Both appear or neither."""
    from gstyle_core.errors import GStyleError

    fmt = _export_format(path)
    try:
        summary = json.loads(Path(summary_file).read_text())
    except (OSError, ValueError) as exc:
        raise GStyleError(f"cannot read the result's summary {summary_file}: {exc}") from exc
    summary.update(scene=str(path), gaussians=int(scene.count))
    return _write_export(path, fmt, scene, summary)


def _export_format(path: Path) -> str:
    """The format ``path``'s suffix names, or a one-line ``GStyleError`` when the studio does not export it."""
    from gstyle_core.errors import GStyleError
    from gstyle_core.io.saver import format_of

    fmt = format_of(path)
    if fmt not in EXPORT_FORMATS:
        raise GStyleError(f"export path must end in .ply, .spz, .compressed.ply or .sog, got {path.name}")
    return fmt


def export_view(snapshot: dict[str, Any], path: Path, config: dict[str, Any], params: dict[str, float],
                last_report: dict[str, Any] | None, died: str) -> str:
    """Save what the studio shows of a run whose worker died (``died``: why, one line): the geometry and colours the
    worker streamed last (``snapshot``), with a summary naming the step they are from, the paintings and the scene
    they came from (``config``: the engine's) and the controls (``params``). Both appear or neither."""
    fmt = _export_format(path)
    scene = scene_from_snapshot(snapshot)
    source = config.get("scene")
    summary = {"scene": str(path), "source_scene": str(Path(source).resolve()) if source else None,
               "gaussians": scene.count, "styles": style_entries(None, config.get("style")),
               "report": last_report, "params": params, "decisions": None, "settings": None,
               "saved_from_view": f"what the studio showed at step {(last_report or {}).get('step')} after {died}"}
    return _write_export(path, fmt, scene, summary)


def _write_export(path: Path, fmt: str, scene: Any, summary: dict[str, Any]) -> str:
    """The scene at ``path`` and its summary beside it, both or neither (``OutputGroup``)."""
    from gstyle_core.atomic import atomic_write_text
    from gstyle_core.io import save_scene
    from gstyle_core.outputs import OutputGroup

    with OutputGroup() as group:
        group.write(summary_path(path), lambda tmp: atomic_write_text(tmp, json.dumps(summary, indent=2, default=str)))
        group.write(path, lambda tmp: save_scene(scene, tmp, fmt=fmt))
    return str(path)


def summary_path(export: str | Path) -> Path:
    """The JSON summary written beside an export: ``name.json`` for ``name.ply``, ``.spz``, ``.compressed.ply`` or
    ``.sog`` (``gstyle_core.outputs.companion``: never cut at an inner dot)."""
    from gstyle_core.outputs import SUMMARY, companion

    return companion(export, SUMMARY)


def style_entries(engine: Any, style: str | list[str] | None) -> list[dict[str, Any]]:
    """[{"path", "weight"}] for the engine's paintings (weights from its settings; equal when it has none)."""
    paths = [style] if isinstance(style, str) else list(style or [])
    weights = list(getattr(getattr(engine, "settings", None), "style_weights", ()) or [])
    if len(weights) != len(paths):
        weights = [1.0 / len(paths)] * len(paths) if paths else []
    return [{"path": str(p), "weight": round(float(w), 6)} for p, w in zip(paths, weights, strict=True)]
