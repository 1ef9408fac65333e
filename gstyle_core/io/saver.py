"""``save_scene``: write a scene as a standard 3DGS binary .ply, an antimatter15 .splat, a Niantic .spz, a
PlayCanvas .compressed.ply or a PlayCanvas SOG (a .sog bundle, or a folder with meta.json), atomically."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..atomic import atomic_write
from ..errors import SceneFormatError
from ..scene import GaussianScene
from .ply_3dgs import write_3dgs_ply
from .ply_compressed_write import write_compressed_ply
from .sog_files import META_NAME
from .sog_write import write_sog_bundle, write_sog_folder
from .splat import write_splat
from .spz_write import write_spz

FORMATS = {".ply": "ply", ".splat": "splat", ".spz": "spz", ".sog": "sog"}
COMPRESSED_PLY_SUFFIX = ".compressed.ply"
SAVE_SUFFIXES = (".ply", COMPRESSED_PLY_SUFFIX, ".splat", ".spz", ".sog", META_NAME)
KINDS = ("ply", "splat", "spz", "compressed-ply", "sog", "sog-folder")


def format_of(path: str | os.PathLike) -> str | None:
    """The output format a file name asks for: "ply", "compressed-ply", "splat", "spz", "sog" (a bundle),
    "sog-folder" (a file named meta.json: SOG's images are written beside it) or None."""
    name = Path(path).name.lower()
    if name.endswith(COMPRESSED_PLY_SUFFIX):
        return "compressed-ply"
    if name == META_NAME:
        return "sog-folder"
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
    """Write ``scene`` to ``path`` as "ply" (3DGS binary little-endian), "splat", "spz" (version 3),
    "compressed-ply" (PlayCanvas), "sog" (PlayCanvas SOG version 2, a bundle) or "sog-folder" (``path`` is the
    meta.json, the images go beside it), chosen by ``fmt`` or the name (``format_of``: ``x.compressed.ply`` is the
    compressed one, ``meta.json`` the SOG folder).

    The file appears complete or not at all (``gstyle_core.atomic.atomic_write``). With ``keep_sh=False`` or a
    degree-0 scene the .ply still carries 45 zero ``f_rest`` fields. .splat, .spz, .compressed.ply and SOG are
    quantised (see ``splat``, ``spz_write``, ``ply_compressed_write``, ``sog_write``); the last three keep SH bands
    only when they hold non-zero coefficients (and ``keep_sh``). A SOG folder's files appear together or not at all.
    """
    p = Path(path)
    kind = fmt or format_of(p)
    if kind not in KINDS:
        raise SceneFormatError(
            f"cannot save {p.name}: unknown output format "
            f"{fmt or p.suffix or '(no extension)'}; use .ply, .compressed.ply, .splat, .spz, .sog or meta.json"
        )
    _check_scene(scene)  # (a directory at ``p``, a full disk, a read-only folder: ``OutputWriteError``)
    if kind == "sog-folder":
        write_sog_folder(p, scene if keep_sh else scene.with_sh_degree(0))
        return
    with atomic_write(p, "wb") as fh:
        if kind == "ply":
            write_3dgs_ply(fh, scene, keep_sh)
        elif kind == "splat":
            write_splat(fh, scene)
        elif kind == "spz":
            write_spz(fh, scene if keep_sh else scene.with_sh_degree(0))
        elif kind == "sog":
            write_sog_bundle(fh, scene if keep_sh else scene.with_sh_degree(0))
        else:
            write_compressed_ply(fh, scene if keep_sh else scene.with_sh_degree(0))
