"""The studio's takes (issue #15, item 6): loading an exported take into its own renderer, comparing it with the
current run, forgetting it, and shelving new exports (``app/takes.py`` keeps the list). A mixin of ``StudioApp``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gstyle_core.errors import GStyleError
from gstyle_core.outputs import BATCH_TABLE, companion

from .export import summary_path
from .splat_data import scene_arrays
from .takes import settings_line

THUMB_SIZE = (96, 72)


def thumbnail_path(output_dir: Path, take_path: str) -> Path:
    """Where a take's thumbnail is kept: ``.thumbs/NAME.png`` in the output folder (beside ``takes.json``)."""
    return Path(output_dir) / ".thumbs" / (Path(take_path).name + ".png")


class TakesView:
    """``StudioApp``'s take methods; the state lives on the app (``takes``, ``take_view``, ``take_shown``,
    ``compare_with_take``)."""

    def show_take(self, index: int, compare: bool = True) -> bool:
        """Load take ``index`` (its exported file) into the take view; ``compare``: stylized left, the take right,
        else the take alone. False (status says why) when its file cannot be read."""
        if not 0 <= index < len(self.takes.takes):
            return False
        take = self.takes.takes[index]
        if not self._same_input(take):
            return self._open_take_of_another_scene(take, compare)
        if self.take_shown != take.path:
            try:
                scene = self.takes.load(index)
            except (GStyleError, OSError) as exc:
                self.panel.status = f"take {take.name}: cannot read {Path(take.path).name}: {exc}"
                return False
            self.take_view.set_scene(scene_arrays(scene))
            self.take_shown = take.path
        self.compare_with_take = compare
        self.view_mode = "compare" if compare else "take"
        self.panel.status = f"{'comparing with' if compare else 'showing'} {take.name} ({Path(take.path).name})"
        return True

    def _same_input(self, take) -> bool:
        """Whether ``take`` was made from the scene on show (its input: a result's original, else the file itself);
        takes of unknown input (exports) are taken to be."""
        if not take.scene or self.loaded is None:
            return True
        shown = self.result.source if self.result is not None and self.result.source else self.loaded.path
        return Path(take.scene).resolve() == Path(shown).resolve()

    def _open_take_of_another_scene(self, take, compare: bool) -> bool:
        """A batch's take of another scene is opened as the studio's scene (a result, framed as its input was and
        compared with its original), not drawn from this scene's cameras; False when it cannot be opened."""
        if not self.open_path(take.path):
            return False
        self.take_shown, self.compare_with_take = None, False
        self.view_mode = "compare" if compare else "stylized"
        self.panel.status = (f"opened {take.name} ({Path(take.path).name}), a take of another scene, as the scene"
                             + ("; comparing with its original" if compare else ""))
        return True

    def open_batch(self, folder: str | Path) -> bool:
        """Shelve the finished jobs of a ``gstyle batch`` folder as takes and compare with the first; False (the
        status line says why) when it has none or its ``batch.csv`` cannot be read."""
        folder = Path(folder)
        try:
            new = self.takes.add_batch(folder)
        except GStyleError as exc:
            self._say(f"could not open the batch: {exc}")
            return False
        if not new:
            self._say(f"no finished jobs in {folder / BATCH_TABLE}")
            return False
        self.show_take(0, compare=True)
        self._say(f"opened the batch {folder.name}: {len(new)} takes to compare ({new[0].name}, ...)")
        return True

    def compare_with_original(self) -> None:
        """Compare view: stylized left, the original right (no take)."""
        self.compare_with_take = False
        self.view_mode = "compare"
        self.panel.status = "comparing with the original"

    def set_view_mode(self, mode: str) -> None:
        """A view mode from the radio buttons or C: "compare" compares with the original (T compares with the
        takes); "take" shows the take loaded, else the newest one."""
        if mode == "compare":
            self.compare_with_original()
        elif mode == "take" and self.takes.takes and self.take_shown is None:
            self.show_take(0, compare=False)
        else:
            if self.panel.status.startswith(("comparing with", "showing")):
                self.panel.status = ""  # "comparing with take N" no longer holds
            self.view_mode = mode

    def forget_take(self, index: int) -> None:
        """Take a take off the shelf (its file stays); the view leaves it if it was shown."""
        take = self.takes.forget(index)
        if take is not None and take.path == self.take_shown:
            self.take_shown, self.compare_with_take = None, False
            if self.view_mode == "take":
                self.view_mode = "stylized"

    def _write_take_thumbnail(self, take) -> None:
        """A small picture of the stylized view as it is now (the take was just exported from it), as a PNG in the
        output folder's ``.thumbs`` (a failure leaves the take without one)."""
        from PIL import Image

        from .gl_io import read_rgb

        if self.stylized.count == 0:
            return
        w, h = THUMB_SIZE
        fbo = self.ctx.simple_framebuffer((w, h))
        try:
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 1.0)
            self.stylized.render(self.control.camera(w, h), fbo)
            rgb = read_rgb(fbo)
            path = thumbnail_path(self.output_dir, take.path)
            path.parent.mkdir(parents=True, exist_ok=True)
            Image.fromarray(rgb).save(path)
        except (OSError, ValueError):
            return
        finally:
            fbo.release()
            self.ctx.screen.use()
        stale = self._take_textures.pop(take.path, None)  # a take exported again to the same file: a new picture
        if stale is not None:
            stale.release()

    def take_texture(self, take) -> tuple[int, tuple[int, int]] | None:
        """The GL texture (id, size) of a take's thumbnail, loaded once from its PNG (a batch's take: its after
        picture, fitted in the thumbnail's size; None without one)."""
        from PIL import Image, ImageOps

        if take.path not in self._take_textures:
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
            self._take_textures[take.path] = texture
        texture = self._take_textures[take.path]
        return None if texture is None else (texture.glo, texture.size)

    def view_key(self) -> str:
        """What the stylized view shows now: the engine run and its geometry and colour versions ("" before any)."""
        st = self.bridge.state if self.bridge is not None else None
        snap = st.snapshot if st is not None else None
        if not snap:
            return ""
        return f"{id(st.exported)}:{snap.get('geometry_version')}:{snap.get('colour_version')}"

    def _shelve_exports(self, exported: list[str]) -> None:
        """New exports become takes (the Gaussian count from the export's JSON summary)."""
        for written in exported:
            path = Path(written)
            try:
                summary = json.loads(summary_path(path).read_text())
                gaussians, line = int(summary["gaussians"]), settings_line(summary)
            except (OSError, ValueError, KeyError, TypeError, AttributeError):
                gaussians, line = self.stylized.count, ""
            take = self.takes.add(path, gaussians, view_key=self.view_key(), settings=line)
            self._write_take_thumbnail(take)
