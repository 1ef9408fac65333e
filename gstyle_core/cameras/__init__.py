"""Cameras: the Camera type, camera sets, readers for common formats, generated views, scene kind."""

from gstyle_core.cameras.camera import Camera
from gstyle_core.cameras.cameraset import CameraSet
from gstyle_core.cameras.classify import classify_scene_kind
from gstyle_core.cameras.colmap import CameraDistortionWarning
from gstyle_core.cameras.generate import generate_cameras, look_at
from gstyle_core.cameras.gs_json import save_cameras_json
from gstyle_core.cameras.images import image_size, load_image, resize_image
from gstyle_core.cameras.loader import load_cameras

__all__ = [
    "Camera",
    "CameraDistortionWarning",
    "CameraSet",
    "classify_scene_kind",
    "generate_cameras",
    "image_size",
    "load_cameras",
    "load_image",
    "look_at",
    "resize_image",
    "save_cameras_json",
]
