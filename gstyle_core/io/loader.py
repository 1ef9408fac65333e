"""``load_scene``: detect the format from the file's content (or a SOG folder), decode it, validate and report."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import SceneFormatError
from ..scene import GaussianScene
from .ply_3dgs import read_3dgs_ply
from .ply_compressed import is_compressed_ply, read_compressed_ply
from .ply_header import is_ply, parse_header
from .report import LoadReport
from .sog import read_sog
from .sog_files import META_NAME, ZIP_MAGIC, BundleFiles, FolderFiles, is_sog_folder
from .source import GZIP_MAGIC, ZSTD_MAGIC, read_scene_bytes
from .splat import looks_like_splat, read_splat
from .spz import is_spz, read_spz
from .validate import validate_and_repair

# The file names these readers are made for (the format itself is told from the content): what file dialogs offer.
# A SOG folder opens by its meta.json (or the folder itself: ``load_scene``).
SCENE_SUFFIXES = (".ply", ".compressed.ply", ".splat", ".spz", ".sog", META_NAME)


def _decode(data: bytes, path: Path) -> tuple[GaussianScene, int, str, list[str], list[str]]:
    """Return (scene, count in file, format name, loader repairs, warnings)."""
    name = path.name
    if is_ply(data):
        header = parse_header(data, name)
        if is_compressed_ply(header):
            scene, count, warnings = read_compressed_ply(data, header, name)
            return scene, count, "ply-playcanvas-compressed", [], warnings
        scene, count, warnings = read_3dgs_ply(data, header, name)
        return scene, count, f"ply-3dgs ({header.fmt})", [], warnings
    if data[:4] == b"NGSP" or (data[:2] == GZIP_MAGIC and is_spz(data)):
        scene, count, warnings, fmt = read_spz(data, name)
        return scene, count, fmt, [], warnings
    splat_name, head = path.suffix.lower() == ".splat", data[:256].lstrip()  # .splat is raw floats: any bytes
    if data[:4] == ZIP_MAGIC and not splat_name:
        scene, count, warnings, fmt = read_sog(BundleFiles(data, name))
        return scene, count, fmt, [], warnings
    json_object = head[:1] == b"{" and head[1:].lstrip()[:1] in (b'"', b"}")
    if path.suffix.lower() == ".json" or (json_object and not splat_name):
        # a SOG meta.json (by its name, or text that opens a JSON object); its images lie beside it
        scene, count, warnings, fmt = read_sog(FolderFiles(path.parent, name))
        return scene, count, fmt, [], warnings
    if data[:4] == ZSTD_MAGIC:
        raise SceneFormatError(f"{name}: zstd-compressed data that is not an SPZ v4 file")
    if splat_name or looks_like_splat(data):
        scene, count, repairs, warnings = read_splat(data, name)
        if not splat_name:
            warnings.append("recognised as .splat from its content")
        return scene, count, "splat", repairs, warnings
    raise SceneFormatError(f"{name}: unknown scene format (expected 3DGS/compressed .ply, .splat, .spz, .sog or "
                           "a SOG meta.json)")


def load_scene(path: str | os.PathLike) -> tuple[GaussianScene, LoadReport]:
    """Load a Gaussian scene from .ply (3DGS or PlayCanvas compressed), .splat, .spz or SOG (a .sog bundle, a
    meta.json, or a folder holding one), detected by content.

    Every loader's output goes through ``validate_and_repair``; the report lists what was changed.
    Malformed files raise ``SceneFormatError`` with a one-line reason.
    """
    p = Path(path)
    if is_sog_folder(p):
        p = p / META_NAME
    data = read_scene_bytes(p)
    try:
        with np.errstate(all="ignore"):  # overflow to inf, NaN from garbage: validate_and_repair handles them
            scene, count, fmt, repairs, warnings = _decode(data, p)
    except SceneFormatError:
        raise
    except (ValueError, TypeError, IndexError, KeyError, OverflowError, MemoryError) as exc:
        raise SceneFormatError(f"{p.name}: malformed scene data ({type(exc).__name__}: {exc})") from None
    scene, more_repairs, dropped = validate_and_repair(scene)
    report = LoadReport(
        fmt, str(p), count, scene.count, scene.sh_degree, repairs + more_repairs, dropped, warnings
    )
    return scene, report
