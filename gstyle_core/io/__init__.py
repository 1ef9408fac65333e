"""Scene readers and writers: 3DGS .ply, PlayCanvas compressed .ply, .splat, .spz and PlayCanvas SOG (a .sog bundle
or a folder with meta.json), in and out.

``load_scene(path) -> (GaussianScene, LoadReport)`` detects the format from the bytes;
``save_scene(scene, path, fmt=None, keep_sh=True)`` writes atomically; ``validate_and_repair`` documents and
applies the checks every loader's output goes through.
"""

from .loader import SCENE_SUFFIXES, load_scene
from .report import LoadReport
from .saver import save_scene
from .validate import validate_and_repair

__all__ = ["SCENE_SUFFIXES", "LoadReport", "load_scene", "save_scene", "validate_and_repair"]
