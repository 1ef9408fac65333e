"""What an engine snapshot holds (``engine.snapshot()``: a dict of numpy arrays) and the scene it describes."""

from __future__ import annotations

from typing import Any

import numpy as np

from gstyle_core.scene import GaussianScene, rgb_to_sh_dc

GEOMETRY_FIELDS = ("means", "log_scales", "quats", "opacity_logits")
# Sent only with a new geometry version: c_gt changes only when the geometry is refitted (the UI reads it then).
FOLLOW_GEOMETRY = (*GEOMETRY_FIELDS, "colors_gt")


def has_scene(snap: dict[str, Any]) -> bool:
    """True when ``snap`` holds a whole scene: every geometry field and one colour per Gaussian."""
    return all(k in snap for k in GEOMETRY_FIELDS) and len(snap.get("colors", ())) == len(snap["means"])


def scene_from_snapshot(snap: dict[str, Any]) -> GaussianScene:
    """The diffuse scene of a snapshot (its colours as the SH DC term; no view-dependent SH)."""
    arrays = [np.asarray(snap[k], np.float32) for k in GEOMETRY_FIELDS]
    return GaussianScene(*arrays, rgb_to_sh_dc(np.asarray(snap["colors"], np.float32)))
