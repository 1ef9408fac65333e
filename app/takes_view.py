"""The studio's takes (issue #15, item 6): loading an exported take into the take view, comparing it with the
current run, forgetting it, shelving new exports, their thumbnails and their rows in the panel (``app/takes.py``
keeps the list). ``TakesView`` is a part of ``StudioApp``."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import moderngl
import numpy as np

from gstyle_core.errors import GStyleError
from gstyle_core.outputs import BATCH_TABLE, companion

from .camera_control import CameraControl
from .events import Handlers
from .export import summary_path
from .panels import PanelState
from .splat_data import scene_arrays
from .status_line import StatusLine
from .studio_views import Views
from .takes import Take, TakeShelf, settings_line

THUMB_SIZE = (96, 72)


def thumbnail_path(output_dir: Path, take_path: str) -> Path:
    """Where a take's thumbnail is kept: ``.thumbs/NAME.png`` in the output folder (beside ``takes.json``)."""
    return Path(output_dir) / ".thumbs" / (Path(take_path).name + ".png")


class TakesView:
    """Owns the shelf of takes (``shelf``, kept in the output folder) and their thumbnails' GL textures. Built with
    the GL context, the panel, the status line, the output folder, the views (the take view and the view mode), the
    camera control (thumbnails are drawn from the view), ``view_key`` (what the stylized view shows now: the engine
    link's), ``input_path`` (the input of the scene on show: the session's) and ``open_path`` (a take of another
    scene opens as the scene: the file opening's)."""

    def __init__(self, ctx: moderngl.Context, panel: PanelState, status: StatusLine, output_dir: Path, *,
                 views: Views, control: CameraControl, view_key: Callable[[], str],
                 input_path: Callable[[], str | None], open_path: Callable[[str], bool]) -> None:
        self.ctx, self.panel, self.status, self.output_dir = ctx, panel, status, output_dir
        self.views, self.control = views, control
        self.view_key, self.input_path, self.open_path = view_key, input_path, open_path
        self.shelf = TakeShelf(output_dir)
        self._textures: dict[str, moderngl.Texture | None] = {}  # thumbnails by take file (None: none to show)

    def show_take(self, index: int, compare: bool = True) -> bool:
        """Load take ``index`` (its exported file) into the take view; ``compare``: stylized left, the take right,
        else the take alone. False (status says why) when its file cannot be read."""
        if not 0 <= index < len(self.shelf.takes):
            return False
        take = self.shelf.takes[index]
        if not self._same_input(take):
            return self._open_take_of_another_scene(take, compare)
        arrays = None
        if self.views.take_shown != take.path:
            try:
                scene = self.shelf.load(index)
            except (GStyleError, OSError) as exc:
                self.status.say(f"take {take.name}: cannot read {Path(take.path).name}: {exc}")
                return False
            arrays = scene_arrays(scene)
        self.views.show_take(take.path, arrays, compare)
        self.status.say(f"{'comparing with' if compare else 'showing'} {take.name} ({Path(take.path).name})")
        return True

    def _same_input(self, take: Take) -> bool:
        """Whether ``take`` was made from the scene on show (its input: a result's original, else the file itself);
        takes of unknown input (exports) are taken to be."""
        shown = self.input_path()
        if not take.scene or shown is None:
            return True
        return Path(take.scene).resolve() == Path(shown).resolve()

    def _open_take_of_another_scene(self, take: Take, compare: bool) -> bool:
        """A batch's take of another scene is opened as the studio's scene (a result, framed as its input was and
        compared with its original), not drawn from this scene's cameras; False when it cannot be opened."""
        if not self.open_path(take.path):
            return False
        self.views.drop_take("compare" if compare else "stylized")
        self.status.say(f"opened {take.name} ({Path(take.path).name}), a take of another scene, as the scene"
                        + ("; comparing with its original" if compare else ""))
        return True

    def open_batch(self, folder: str | Path) -> bool:
        """Shelve the finished jobs of a ``gstyle batch`` folder as takes and compare with the first; False (the
        status line says why) when it has none or its ``batch.csv`` cannot be read."""
        folder = Path(folder)
        try:
            new = self.shelf.add_batch(folder)
        except GStyleError as exc:
            self.status.tell(f"could not open the batch: {exc}")
            return False
        if not new:
            self.status.tell(f"no finished jobs in {folder / BATCH_TABLE}")
            return False
        self.show_take(0, compare=True)
        self.status.tell(f"opened the batch {folder.name}: {len(new)} takes to compare ({new[0].name}, ...)")
        return True

    def compare_with_original(self) -> None:
        """Compare view: stylized left, the original right (no take)."""
        self.views.compare(with_take=False)
        self.status.say("comparing with the original")

    def set_view_mode(self, mode: str) -> None:
        """A view mode from the radio buttons or C: "compare" compares with the original (T compares with the
        takes); "take" shows the take loaded, else the newest one."""
        if mode == "compare":
            self.compare_with_original()
        elif mode == "take" and self.shelf.takes and self.views.take_shown is None:
            self.show_take(0, compare=False)
        else:
            self.status.clear_if(("comparing with", "showing"))  # "comparing with take N" no longer holds
            self.views.set_mode(mode)

    def forget_take(self, index: int) -> None:
        """Take a take off the shelf (its file stays); the view leaves it if it was shown."""
        take = self.shelf.forget(index)
        if take is not None and take.path == self.views.take_shown:
            self.views.drop_take()

    def _write_thumbnail(self, take: Take) -> None:
        """A small picture of the stylized view as it is now (the take was just exported from it), as a PNG in the
        output folder's ``.thumbs`` (a failure leaves the take without one)."""
        from PIL import Image

        from .gl_io import read_rgb

        stylized = self.views.stylized
        if stylized.count == 0:
            return
        w, h = THUMB_SIZE
        fbo = self.ctx.simple_framebuffer((w, h))
        try:
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 1.0)
            stylized.render(self.control.camera(w, h), fbo)
            rgb = read_rgb(fbo)
            path = thumbnail_path(self.output_dir, take.path)
            path.parent.mkdir(parents=True, exist_ok=True)
            Image.fromarray(rgb).save(path)
        except (OSError, ValueError):
            return
        finally:
            fbo.release()
            self.ctx.screen.use()
        stale = self._textures.pop(take.path, None)  # a take exported again to the same file: a new picture
        if stale is not None:
            stale.release()

    def texture(self, take: Take) -> tuple[int, tuple[int, int]] | None:
        """The GL texture (id, size) of a take's thumbnail, loaded once from its PNG (a batch's take: its after
        picture, fitted in the thumbnail's size; None without one)."""
        from PIL import Image, ImageOps

        if take.path not in self._textures:
            texture = None
            try:
                if take.batch:
                    with Image.open(companion(take.path, "_after.png")) as after:
                        rgb = np.asarray(ImageOps.contain(after.convert("RGB"), THUMB_SIZE))
                else:
                    rgb = np.asarray(Image.open(thumbnail_path(self.output_dir, take.path)).convert("RGB"))
                texture = self.ctx.texture((rgb.shape[1], rgb.shape[0]), 3, rgb.tobytes(), alignment=1)
            except (OSError, ValueError):
                pass
            self._textures[take.path] = texture
        texture = self._textures[take.path]
        return None if texture is None else (texture.glo, texture.size)

    def shelve_exports(self, exported: list[str]) -> str:
        """New exports become takes (the Gaussian count from the export's JSON summary); the newest take's name."""
        for written in exported:
            path = Path(written)
            try:
                summary = json.loads(summary_path(path).read_text())
                gaussians, line = int(summary["gaussians"]), settings_line(summary)
            except (OSError, ValueError, KeyError, TypeError, AttributeError):
                gaussians, line = self.views.stylized.count, ""
            take = self.shelf.add(path, gaussians, view_key=self.view_key(), settings=line)
            self._write_thumbnail(take)
        return self.shelf.takes[0].name

    # ----------------------------------------------------------------- the panel
    def fill_panel(self) -> None:
        """The takes' rows in the panel: names, labels, settings, thumbnails, which differ from the view now, the
        take shown and whether the compare view compares with it."""
        p, takes = self.panel, self.shelf.takes
        p.take_names = [t.name for t in takes]
        p.take_labels = [t.label for t in takes]
        p.take_settings = [t.settings for t in takes]
        p.take_thumbnails = [self.texture(t) for t in takes]
        now = self.view_key()
        p.take_differs = [not now or t.view_key != now for t in takes]
        shown = [i for i, t in enumerate(takes) if t.path == self.views.take_shown]
        p.take_shown = shown[0] if shown else -1
        p.compare_with_take = self.views.compare_with_take and p.take_shown >= 0

    def show_write_error(self) -> None:
        """A failure to save ``takes.json`` (one line) after the status; the shelf goes on for this session."""
        error = self.shelf.pop_write_error()
        if error:
            status = self.status.text
            self.status.say(f"{status}; {error} (the takes are kept for this session)" if status else error)

    def release(self) -> None:
        """Free the thumbnails' textures."""
        for texture in self._textures.values():
            if texture is not None:
                texture.release()

    def commands(self) -> Handlers:
        """The panel's commands this part carries out: the view mode, show, compare, rename or forget a take."""
        return {"view_mode": lambda args: self.set_view_mode(args["mode"]),
                "show_take": lambda args: self.show_take(int(args["index"]), compare=bool(args.get("compare", True))),
                "compare_original": lambda _args: self.compare_with_original(),
                "rename_take": lambda args: self.shelf.rename(int(args["index"]), str(args["name"])),
                "forget_take": lambda args: self.forget_take(int(args["index"]))}
