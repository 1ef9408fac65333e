"""Fuzz cases for every scene reader, camera reader and style-image loader.

Shared by ``tests/test_fuzz_readers.py`` (driven by hypothesis) and ``bench/soak.py`` (driven by ``random``).
Every case starts from a small valid file made by our writers (or a small encoder for formats we only read)
and applies a few mutations. All choices go through a :class:`Draw`, so hypothesis can shrink failures.

Checkers (``check_scene_file``, ``check_camera_source``, ``check_style_image``) run the reader and return
"ok" (a valid result) or "error" (a one-line ``GStyleError`` of the right kind); anything else raises
:class:`FuzzFailure` or lets the unexpected exception through.
"""

from tests.fuzzcases.cameras import CAMERA_FORMATS, check_camera_source, write_camera_case, write_valid_cameras
from tests.fuzzcases.common import Draw, FuzzFailure, RandomDraw, run_bounded
from tests.fuzzcases.images import IMAGE_FORMATS, check_style_image, valid_image, write_image_case
from tests.fuzzcases.scenes import SCENE_FORMATS, check_scene_file, scene_case, valid_scene_file

__all__ = [
    "CAMERA_FORMATS",
    "IMAGE_FORMATS",
    "SCENE_FORMATS",
    "Draw",
    "FuzzFailure",
    "RandomDraw",
    "check_camera_source",
    "check_scene_file",
    "check_style_image",
    "run_bounded",
    "scene_case",
    "valid_image",
    "valid_scene_file",
    "write_camera_case",
    "write_image_case",
    "write_valid_cameras",
]
