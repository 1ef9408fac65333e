"""A selected region: which Gaussians a run stylizes (issue #15, item 4).

A selection is a boolean mask over the input scene's Gaussians, made from an axis-aligned box in scene
coordinates (``--region x0,y0,z0,x1,y1,z1``: the Gaussians whose centres lie inside, faces included) or from a
screen rectangle of a camera (the studio's rectangle tool: the Gaussians in front of the camera whose projected
centres fall inside). The engine (``stylizer.py``) pre-processes, splits, refits and stylizes only the selected
Gaussians (children inherit the selection); the others keep every attribute and leave the export exactly as they
came in (``Stylizer.stylized_scene``), and the losses see only the selected part (the objective's coverage is the
selected Gaussians' rendered weight). A box may have a soft edge (``region_feather``, scene units): the Gaussians up
to that far outside it are selected too, and each one's stylized colour is shown and exported mixed with its own by
``feather_weights`` (1 inside the box, falling to 0 at the feather's distance), so the style fades out instead of
stopping at a seam (``feather.feathered_colours``). Nothing here imports torch: the studio uses it on its UI thread.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import GStyleError

Box = tuple[float, float, float, float, float, float]


class RegionError(GStyleError, ValueError):
    """A region that cannot be used: malformed box, or one that selects no Gaussian."""


def check_region(box: Sequence[float]) -> Box:
    """``box`` as six floats (x0, y0, z0, x1, y1, z1) if it is a usable box, else ``RegionError`` saying why."""
    try:
        values = [float(v) for v in box]
    except (TypeError, ValueError):
        raise RegionError(f"region must be six numbers x0,y0,z0,x1,y1,z1, got {box!r}") from None
    if len(values) != 6:
        raise RegionError(f"region must be six numbers x0,y0,z0,x1,y1,z1 (two corners of a box), got {len(values)}")
    if not all(math.isfinite(v) for v in values):
        raise RegionError(f"region corners must be finite numbers, got {','.join(f'{v:g}' for v in values)}")
    for axis, lo, hi in zip("xyz", values[:3], values[3:], strict=True):
        if lo > hi:
            raise RegionError(f"region: {axis}0 = {lo:g} is larger than {axis}1 = {hi:g} (give the low corner first)")
    return tuple(values)  # type: ignore[return-value]


def parse_region(text: str) -> Box:
    """``"x0,y0,z0,x1,y1,z1"`` -> a checked box (``RegionError`` otherwise)."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise RegionError(f"region must be six comma-separated numbers x0,y0,z0,x1,y1,z1, got {text!r}") from None
    return check_region(values)


def box_mask(means: np.ndarray, box: Sequence[float]) -> np.ndarray:
    """Bool [N]: the centres inside ``box`` (faces included)."""
    b = np.asarray(check_region(box), np.float64)
    m = np.asarray(means, np.float64).reshape(-1, 3)
    return np.all((m >= b[:3]) & (m <= b[3:]), axis=1)


def grown_box(box: Sequence[float], by: float) -> Box:
    """``box`` grown by ``by`` scene units on every side (the band a feathered region also stylizes)."""
    b = check_region(box)
    return check_region([*(v - by for v in b[:3]), *(v + by for v in b[3:])])


def feather_weights(means: np.ndarray, box: Sequence[float], feather: float) -> np.ndarray:
    """Float [N] in [0, 1]: how much of its stylized colour each centre shows in a feathered region: 1 inside
    ``box``, falling linearly with the distance outside it to 0 at ``feather`` scene units (``feather`` 0: the box's
    hard edge)."""
    b = np.asarray(check_region(box), np.float64)
    m = np.asarray(means, np.float64).reshape(-1, 3)
    outside = np.maximum(b[:3] - m, 0.0) + np.maximum(m - b[3:], 0.0)  # per axis; one of the two is 0
    distance = np.linalg.norm(outside, axis=1)
    if feather <= 0:
        return (distance == 0).astype(np.float32)
    return np.clip(1.0 - distance / float(feather), 0.0, 1.0).astype(np.float32)


def selected_box(settings) -> Box | None:
    """The box a run selects by: the region's, grown by its feather (None without a region)."""
    if settings.region is None:
        return None
    feather = float(getattr(settings, "region_feather", 0.0))
    return grown_box(settings.region, feather) if feather > 0 else check_region(settings.region)


def rect_mask(means: np.ndarray, camera, rect: Sequence[float]) -> np.ndarray:
    """Bool [N]: the centres in front of ``camera`` (a ``cameras.Camera``) whose projection falls in the pixel
    rectangle ``rect`` = (x0, y0, x1, y1) (any two opposite corners, image pixels, y down)."""
    x0, y0, x1, y1 = (float(v) for v in rect)
    x0, x1 = sorted((x0, x1))
    y0, y1 = sorted((y0, y1))
    m = np.asarray(means, np.float64).reshape(-1, 3)
    w2c = np.asarray(camera.world_to_cam, np.float64)
    pc = m @ w2c[:3, :3].T + w2c[:3, 3]
    z = pc[:, 2]
    front = z > 1e-6
    safe = np.where(front, z, 1.0)
    u = camera.fx * pc[:, 0] / safe + camera.cx
    v = camera.fy * pc[:, 1] / safe + camera.cy
    return front & (u >= x0) & (u <= x1) & (v >= y0) & (v <= y1)


def selection_mask(means: np.ndarray, box: Sequence[float] | None = None,
                   selection: np.ndarray | None = None) -> np.ndarray | None:
    """The selected Gaussians: inside ``box`` and/or in ``selection`` (a bool mask, both: the Gaussians in both);
    None when neither is given (the whole scene). ``RegionError`` when the result selects nothing."""
    n = int(np.asarray(means).reshape(-1, 3).shape[0])
    if box is None and selection is None:
        return None
    mask = np.ones(n, bool)
    what = []
    if box is not None:
        mask &= box_mask(means, box)
        what.append("box " + ",".join(f"{v:g}" for v in check_region(box)))
    if selection is not None:
        sel = np.asarray(selection)
        if sel.shape != (n,):
            raise RegionError(f"selection mask has shape {sel.shape}, the scene has {n} Gaussians")
        mask &= sel.astype(bool)
        what.append("the given selection")
    if not mask.any():
        lo, hi = np.asarray(means).reshape(-1, 3).min(0), np.asarray(means).reshape(-1, 3).max(0)
        bounds = ",".join(f"{v:.3g}" for v in (*lo, *hi))
        raise RegionError(f"the region ({' and '.join(what)}) selects none of the {n:,} Gaussians; their centres "
                          f"span {bounds} (x0,y0,z0,x1,y1,z1)")
    return mask


def region_note(box: Sequence[float] | None, selected: int, total: int, feather: float = 0.0) -> str:
    """One line for the run's decisions and OUT.json."""
    where = ("box " + ",".join(f"{v:g}" for v in box)) if box is not None else "a selection"
    soft = (f" (its edge feathered over {feather:g} scene units: the style fades out to the scene's own colours "
            "there)") if box is not None and feather > 0 else ""
    return (f"{where}{soft}: {selected:,} of {total:,} Gaussians selected and stylized; the other "
            f"{total - selected:,} are exported untouched (every attribute, SH included)")
