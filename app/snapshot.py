"""What an engine snapshot holds (``engine.snapshot()``: a dict of numpy arrays) and the scene it describes."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from gstyle_core.scene import GaussianScene, rgb_to_sh_dc

GEOMETRY_FIELDS = ("means", "log_scales", "quats", "opacity_logits")
# Sent only with a new geometry version: c_gt changes only when the geometry is refitted (the UI reads it then).
FOLLOW_GEOMETRY = (*GEOMETRY_FIELDS, "colors_gt")


GEOMETRY_SEND_INTERVAL_S = 0.5  # changed geometry goes to the UI at most this often while the engine steps


class GeometrySends:
    """The worker's side of streamed geometry: a refit changes it every step (2 a second on a 1.26 M-Gaussian run on
    a cut) and each send is all of it for the UI to unpack, which shows it at most every 0.5 s anyway
    (``studio_sync``). So while the engine steps, changed geometry is sent at most every ``GEOMETRY_SEND_INTERVAL_S``,
    and colours of a count the UI has no geometry for yet wait for theirs."""

    def __init__(self) -> None:
        self.version: Any = object()  # the geometry version last sent
        self.at: float | None = None  # when (time.monotonic; None: none sent yet)
        self.count = -1  # its Gaussians

    def shape(self, snap: dict[str, Any], due: bool) -> dict[str, Any] | None:
        """``snap`` as it is to be sent: without the geometry fields when they are unchanged or held back (its
        ``geometry_version`` then the one last sent); None when nothing is to be sent now. ``due``: send changed
        geometry now (paused, a finished run, a forced send)."""
        changed = snap.get("geometry_version") != self.version
        held = changed and not due and self.at is not None and time.monotonic() - self.at < GEOMETRY_SEND_INTERVAL_S
        if held and len(snap.get("colors", ())) != self.count:
            return None
        if changed and not held:
            self.version, self.at = snap.get("geometry_version"), time.monotonic()
            self.count = len(snap.get("means", ()))
            return snap
        for key in FOLLOW_GEOMETRY:
            snap.pop(key, None)
        snap["geometry_version"] = self.version  # the version of the geometry the UI has (not of one held back)
        return snap


def has_scene(snap: dict[str, Any]) -> bool:
    """True when ``snap`` holds a whole scene: every geometry field and one colour per Gaussian."""
    return all(k in snap for k in GEOMETRY_FIELDS) and len(snap.get("colors", ())) == len(snap["means"])


def scene_from_snapshot(snap: dict[str, Any]) -> GaussianScene:
    """The diffuse scene of a snapshot (its colours as the SH DC term; no view-dependent SH)."""
    arrays = [np.asarray(snap[k], np.float32) for k in GEOMETRY_FIELDS]
    return GaussianScene(*arrays, rgb_to_sh_dc(np.asarray(snap["colors"], np.float32)))
