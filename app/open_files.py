"""Opening files in the studio: a scene (with its cameras) or a painting, dropped on the window or chosen in a file
dialog. ``OpenFiles`` is a mixin of ``StudioApp`` (it uses the app's panel, scene, style and engine methods)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from gstyle_core.cameras.camera import Camera
from gstyle_core.errors import GStyleError
from gstyle_core.scene import GaussianScene

SCENE_SUFFIXES = (".ply", ".splat", ".spz")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".webp", ".bmp", ".tif", ".tiff")


@dataclass
class LoadedScene:
    """The scene being stylized, with the cameras that came with it (or were generated)."""

    path: str
    scene: GaussianScene
    cameras: list[Camera]


def load_scene_with_cameras(scene_path: str | None, cameras_path: str | None) -> LoadedScene:
    """Load a scene file (default: the bundled demo) and its cameras (given, else generated)."""
    from gstyle_core.assets import DEMO_SCENE
    from gstyle_core.render_cli import load_scene_and_cameras

    path = Path(scene_path) if scene_path else DEMO_SCENE
    if not path.exists():
        what = "scene file" if scene_path else "bundled demo scene"
        raise GStyleError(f"{what} not found: {path}")
    scene, _report, cams = load_scene_and_cameras(scene_path, cameras_path)
    return LoadedScene(str(scene_path or DEMO_SCENE), scene, list(cams.cameras))


class OpenFiles:
    """``StudioApp``'s file opening; the open dialog's state lives on the app (``_dialog``)."""

    def on_drop(self, paths) -> None:
        """glfw drop callback: open the first dropped file (a scene or a style image); more files are ignored."""
        paths = list(paths)
        if paths:
            self.open_path(paths[0])
            if len(paths) > 1:
                self.panel.status += f" ({len(paths) - 1} more dropped file(s) ignored)"

    def open_path(self, path: str, style_slot: int = 0) -> None:
        """Open a dropped or chosen file: a scene (.ply/.splat/.spz) or a style image (``style_slot`` 1: as the second
        painting of a mix)."""
        suffix = Path(path).suffix.lower()
        try:
            if suffix in SCENE_SUFFIXES and style_slot == 0:
                self.set_scene(load_scene_with_cameras(path, None))
            elif suffix in IMAGE_SUFFIXES:
                self.set_style(path, style_slot)
            else:
                self.panel.status = f"not a scene or image: {Path(path).name}"
                return
        except GStyleError as exc:
            self.panel.status = f"could not open {Path(path).name}: {exc}"
            return
        self.panel.status = f"opened {Path(path).name}"
        if self.bridge is not None:
            self.start_engine()

    def _open_dialog(self, kind: str) -> None:
        try:
            from imgui_bundle import portable_file_dialogs as pfd
        except ImportError:
            self.panel.status = "file dialogs unavailable; drop a file on the window"
            return
        if kind == "open_scene":
            dialog = pfd.open_file("Open scene", "", ["Gaussian scenes", "*.ply *.splat *.spz"])
        else:
            title = "Open second style image" if kind == "open_style2" else "Open style image"
            dialog = pfd.open_file(title, "", ["Images", "*.png *.jpg *.jpeg *.webp *.bmp"])
        self._dialog = (kind, dialog)

    def _poll_dialog(self) -> None:
        if self._dialog is None or not self._dialog[1].ready(0):
            return
        kind, dialog = self._dialog
        self._dialog = None
        for path in dialog.result()[:1]:
            self.open_path(path, style_slot=1 if kind == "open_style2" else 0)
