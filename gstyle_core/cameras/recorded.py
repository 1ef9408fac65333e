"""Generated cameras recorded beside a result: a stylized scene renders from its input's cameras.

A bare scene file gets cameras generated around its Gaussians (``generate_cameras``). A stylized result of it may
hold Gaussians the input had not (splits), so cameras generated around the result would frame it differently and
before/after pictures of "camera K" would not compare. ``gstyle stylize`` therefore writes the parameters that made
the input's cameras (``CameraSet.generated``: kind, count, image size, field of view, up, the framed sphere's centre
and radius) and the input's framing box (``framing.scene_box``) into OUT.json under ``RECORD_KEY``;
``recorded_cameras`` makes the same cameras again for a scene that has such a summary beside it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from gstyle_core.cameras.cameraset import CameraSet
from gstyle_core.errors import GStyleError

RECORD_KEY = "generated_cameras"  # the OUT.json key of the input's generated cameras
_VECTORS = ("up", "centre")


def camera_record(cams: Any, means: np.ndarray) -> dict | None:
    """What OUT.json records of ``cams`` (a ``CameraSet``) generated around the input's ``means``: the parameters
    that make them again and the input's framing box (``box``: [lo, hi]; a record made again keeps its own); None
    for cameras not generated."""
    from gstyle_core.cameras.framing import scene_box

    generated = getattr(cams, "generated", None)
    if not generated:
        return None
    if record_box(generated) is not None:
        return dict(generated)
    lo, hi = scene_box(means)
    return {**generated, "box": [[float(v) for v in lo], [float(v) for v in hi]]}


def cameras_from_record(record: dict, where: str = "the record") -> CameraSet:
    """The cameras ``record`` (``camera_record``) describes, exactly as they were generated; a malformed record is
    a one-line ``GStyleError`` naming ``where``."""
    from gstyle_core.cameras.generate import generate_cameras

    try:  # generate_cameras refuses a non-finite centre, radius or up (ValueError)
        vectors = {key: np.asarray(record[key], np.float64).reshape(3) for key in _VECTORS}
        cams = generate_cameras(np.zeros((0, 3)), kind=str(record["kind"]), count=int(record["count"]),
                                width=int(record["width"]), height=int(record["height"]),
                                fov_deg=float(record["fov_deg"]), up=vectors["up"], centre=vectors["centre"],
                                radius=float(record["radius"]))
    except KeyError as exc:
        raise GStyleError(f"{where}: the recorded cameras ({RECORD_KEY}) are malformed: no {exc}") from None
    except (TypeError, ValueError) as exc:
        raise GStyleError(f"{where}: the recorded cameras ({RECORD_KEY}) are malformed: {exc}") from None
    return cams


def record_box(record: dict | None) -> tuple[np.ndarray, np.ndarray] | None:
    """The input's framing box (lo, hi) a record holds, or None (no record, or no usable box in it)."""
    try:
        lo, hi = (np.asarray(corner, np.float64).reshape(3) for corner in record["box"])
    except (KeyError, TypeError, ValueError):
        return None
    return (lo, hi) if np.isfinite(lo).all() and np.isfinite(hi).all() and (hi >= lo).all() else None


def _summary(scene_path: str | os.PathLike) -> tuple[dict, Path] | None:
    """The summary beside ``scene_path`` (``outputs.companion``: ``OUT.json`` beside ``OUT.ply``) and its path; None
    when there is none or it is no JSON object."""
    from gstyle_core.outputs import SUMMARY, companion

    path = companion(scene_path, SUMMARY)
    if Path(path).resolve() == Path(scene_path).resolve() or not path.is_file():
        return None
    try:
        summary = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return (summary, path) if isinstance(summary, dict) else None


def recorded_cameras(scene_path: str | os.PathLike) -> CameraSet | None:
    """The input's cameras as the summary beside ``scene_path`` records them: generated ones from their record, or
    the cameras file or folder the run was given (``camera_source``) while it is still there; None otherwise."""
    found = _summary(scene_path)
    if found is None:
        return None
    summary, path = found
    record = summary.get(RECORD_KEY)
    if isinstance(record, dict):
        cams = cameras_from_record(record, str(path))
        cams.source = f"{cams.source}, the input's, recorded in {path.name}"
        cams.generated = record
        return cams
    given = summary.get("camera_source")
    if isinstance(given, str) and given and Path(given).exists():
        from . import load_cameras

        try:
            cams = load_cameras(given)
        except (GStyleError, OSError, ValueError):
            return None  # moved or changed since: generated around the result instead
        cams.source = f"{cams.source}, the input's, named in {path.name}"
        return cams
    return None
