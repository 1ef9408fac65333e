"""``save_scene``: write a scene as a standard 3DGS binary .ply or an antimatter15 .splat, atomically."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..atomic import atomic_write
from ..errors import SceneFormatError
from ..scene import GaussianScene
from .ply_3dgs import write_3dgs_ply
from .splat import write_splat

FORMATS = {".ply": "ply", ".splat": "splat"}


def _check_scene(scene: GaussianScene) -> None:
    n = scene.count
    shapes = {"means": (n, 3), "log_scales": (n, 3), "quats": (n, 4), "opacity_logits": (n,), "sh_dc": (n, 3)}
    for field, shape in shapes.items():
        if np.shape(getattr(scene, field)) != shape:
            raise SceneFormatError(
                f"cannot save: {field} has shape {np.shape(getattr(scene, field))}, expected {shape}"
            )
    rest = np.shape(scene.sh_rest)
    if len(rest) != 3 or rest[0] != n or rest[2] != 3 or rest[1] not in (0, 3, 8, 15):
        raise SceneFormatError(f"cannot save: sh_rest has shape {rest}, expected ({n}, 0/3/8/15, 3)")


def save_scene(
    scene: GaussianScene, path: str | os.PathLike, *, fmt: str | None = None, keep_sh: bool = True
) -> None:
    """Write ``scene`` to ``path`` as "ply" (3DGS binary little-endian) or "splat" (by ``fmt`` or extension).

    The file appears complete or not at all (``gstyle_core.atomic.atomic_write``). With ``keep_sh=False`` or a
    degree-0 scene the .ply still carries 45 zero ``f_rest`` fields. .splat is quantised (see ``splat``).
    """
    p = Path(path)
    kind = fmt or FORMATS.get(p.suffix.lower())
    if kind not in ("ply", "splat"):
        raise SceneFormatError(
            f"cannot save {p.name}: unknown output format "
            f"{fmt or p.suffix or '(no extension)'}; use .ply or .splat"
        )
    if p.is_dir():
        raise SceneFormatError(f"cannot save: {p} is a directory")
    _check_scene(scene)
    with atomic_write(p, "wb") as fh:
        if kind == "ply":
            write_3dgs_ply(fh, scene, keep_sh)
        else:
            write_splat(fh, scene)
