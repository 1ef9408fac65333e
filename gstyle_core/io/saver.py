"""``save_scene``: write a scene as a standard 3DGS binary .ply, an antimatter15 .splat, a Niantic .spz or a
PlayCanvas .compressed.ply, atomically."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..atomic import atomic_write
from ..errors import SceneFormatError
from ..scene import GaussianScene
from .ply_3dgs import write_3dgs_ply
from .ply_compressed_write import write_compressed_ply
from .splat import write_splat
from .spz_write import write_spz

FORMATS = {".ply": "ply", ".splat": "splat", ".spz": "spz"}
COMPRESSED_PLY_SUFFIX = ".compressed.ply"
SAVE_SUFFIXES = (".ply", COMPRESSED_PLY_SUFFIX, ".splat", ".spz")


def format_of(path: str | os.PathLike) -> str | None:
    """The output format a file name asks for: "ply", "compressed-ply", "splat", "spz" or None."""
    name = Path(path).name.lower()
    if name.endswith(COMPRESSED_PLY_SUFFIX):
        return "compressed-ply"
    return FORMATS.get(Path(name).suffix)


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
    """Write ``scene`` to ``path`` as "ply" (3DGS binary little-endian), "splat", "spz" (version 3) or
    "compressed-ply" (PlayCanvas), chosen by ``fmt`` or the name (``format_of``: ``x.compressed.ply`` is the
    compressed one).

    The file appears complete or not at all (``gstyle_core.atomic.atomic_write``). With ``keep_sh=False`` or a
    degree-0 scene the .ply still carries 45 zero ``f_rest`` fields. .splat, .spz and .compressed.ply are
    quantised (see ``splat``, ``spz_write``, ``ply_compressed_write``); the last two keep SH bands only when they
    hold non-zero coefficients (and ``keep_sh``).
    """
    p = Path(path)
    kind = fmt or format_of(p)
    if kind not in ("ply", "splat", "spz", "compressed-ply"):
        raise SceneFormatError(
            f"cannot save {p.name}: unknown output format "
            f"{fmt or p.suffix or '(no extension)'}; use .ply, .compressed.ply, .splat or .spz"
        )
    _check_scene(scene)  # (a directory at ``p``, a full disk, a read-only folder: ``OutputWriteError``)
    with atomic_write(p, "wb") as fh:
        if kind == "ply":
            write_3dgs_ply(fh, scene, keep_sh)
        elif kind == "splat":
            write_splat(fh, scene)
        elif kind == "spz":
            write_spz(fh, scene if keep_sh else scene.with_sh_degree(0))
        else:
            write_compressed_ply(fh, scene if keep_sh else scene.with_sh_degree(0))
