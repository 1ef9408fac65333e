"""The studio's exports: the stylized scene as .ply, .spz or .compressed.ply with a JSON summary beside it (written
by the engine worker, which holds the engine)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .snapshot import scene_from_snapshot

EXPORT_FORMATS = ("ply", "spz", "compressed-ply")  # what the studio exports (the web formats for web viewers)


def export_engine(engine: Any, path: Path, last_report: dict[str, Any] | None, params: dict[str, float],
                  style: str | list[str] | None = None) -> str:
    """Save the stylized scene as .ply, .spz or .compressed.ply (``gstyle_core.io.save_scene``) and a JSON summary
    beside it (``name.json``; ``style``: the engine's painting path(s), named there with their weights)."""
    from gstyle_core.atomic import atomic_write_text
    from gstyle_core.errors import GStyleError
    from gstyle_core.io import save_scene
    from gstyle_core.io.saver import format_of

    if format_of(path) not in EXPORT_FORMATS:
        raise GStyleError(f"export path must end in .ply, .spz or .compressed.ply, got {path.name}")
    scene = engine.stylized_scene() if hasattr(engine, "stylized_scene") else scene_from_snapshot(engine.snapshot())
    save_scene(scene, path)
    summary = {"scene": str(path), "gaussians": scene.count, "styles": style_entries(engine, style),
               "report": last_report, "params": params,
               "decisions": getattr(engine, "decisions", None),
               "settings": engine.settings.to_dict() if hasattr(getattr(engine, "settings", None), "to_dict")
               else None}
    atomic_write_text(summary_path(path), json.dumps(summary, indent=2, default=str))
    return str(path)


def summary_path(export: str | Path) -> Path:
    """The JSON summary written beside an export: ``name.json`` for ``name.ply``, ``.spz`` or ``.compressed.ply``."""
    from gstyle_core.io.saver import COMPRESSED_PLY_SUFFIX, format_of

    path = Path(export)
    stem = path.name[: -len(COMPRESSED_PLY_SUFFIX)] if format_of(path) == "compressed-ply" else path.stem
    return path.with_name(stem + ".json")


def style_entries(engine: Any, style: str | list[str] | None) -> list[dict[str, Any]]:
    """[{"path", "weight"}] for the engine's paintings (weights from its settings; equal when it has none)."""
    paths = [style] if isinstance(style, str) else list(style or [])
    weights = list(getattr(getattr(engine, "settings", None), "style_weights", ()) or [])
    if len(weights) != len(paths):
        weights = [1.0 / len(paths)] * len(paths) if paths else []
    return [{"path": str(p), "weight": round(float(w), 6)} for p, w in zip(paths, weights, strict=True)]
