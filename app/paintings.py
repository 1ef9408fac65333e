"""The studio's painting(s): the painting opened, a second one mixed in with the mix slider, removed; their
thumbnails, the engine config's ``style`` (and ``style_weights``), and a painting choice as an undo step of its own
(``PaintingEdit``: when no result was replaced). ``Paintings`` is a mixin of ``StudioApp``."""

from __future__ import annotations

import numpy as np

from .edit_history import Edit, PaintingEdit


class Paintings:
    """``StudioApp``'s painting(s) and their undo steps."""

    def set_style(self, path: str, slot: int = 0, mix: float | None = None) -> None:
        """Use a new style image (``slot`` 0: the painting; 1: a second painting mixed in with the mix slider, at
        ``mix``, by default the slider's value or an even mix): thumbnail in the panel; the caller restarts the
        engine with it."""
        from gstyle_core.images import load_style_image

        rgb = load_style_image(path)
        thumb = np.ascontiguousarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8))
        self._release_style_texture(slot)
        h, w = thumb.shape[:2]
        texture = self.ctx.texture((w, h), 3, thumb.tobytes(), alignment=1)
        self._style_textures[slot] = texture
        if slot == 0:
            self.panel.style_texture, self.panel.style_size, self.panel.style_path = texture.glo, (w, h), str(path)
        else:
            self.panel.style2_texture, self.panel.style2_size, self.panel.style2_path = texture.glo, (w, h), str(path)
            if mix is not None:
                self.panel.params["style_mix"] = float(mix)
            elif not self.panel.params.get("style_mix"):  # a new second painting starts at an even mix
                self.panel.params["style_mix"] = 0.5
        self._update_style_config()

    def remove_second_style(self) -> None:
        """Back to one painting (the caller restarts the engine)."""
        self._release_style_texture(1)
        self.panel.style2_texture, self.panel.style2_path = None, ""
        self.panel.params["style_mix"] = 0.0
        self._update_style_config()

    def _release_style_texture(self, slot: int) -> None:
        if self._style_textures[slot] is not None:
            self._style_textures[slot].release()
            self._style_textures[slot] = None

    def _update_style_config(self) -> None:
        """The engine config's style: the painting's path, or both paths with their weights (the mix slider)."""
        p = self.panel
        if p.style2_path and p.style_path:
            mix = float(p.params.get("style_mix", 0.5))
            self.engine_config["style"] = [p.style_path, p.style2_path]
            self.engine_config["style_weights"] = (1.0 - mix, mix)
        else:
            self.engine_config["style"] = p.style_path or None
            self.engine_config.pop("style_weights", None)

    # ------------------------------------------------------------------ undo steps
    def painting_state(self) -> tuple[str, str, float]:
        """The painting(s) chosen now: (painting, second painting or "", mix)."""
        p = self.panel
        return p.style_path or "", p.style2_path or "", float(p.params.get("style_mix", 0.0))

    def painting_step(self, before: tuple[str, str, float], last_step: Edit | None) -> None:
        """A painting was opened, mixed in or removed: one undo step, unless it changed nothing or a result it
        replaced is the step already (``last_step``: the newest step before the change)."""
        after = self.painting_state()
        if after != before and self.history.last() is last_step and not self._restoring:
            self.history.record_result(PaintingEdit(before, after))

    def undo_or_redo_painting(self, edit: PaintingEdit, name: str) -> None:
        """Put the painting(s) before (undo) or after (redo) ``edit`` back; the engine restarts with them. Undo saves
        a result made after the change first; redo opens it again instead of starting over."""
        if name == "undo":
            edit.result_after = self.save_result() or edit.result_after
        elif edit.result_after is not None and self._wait_for(edit.result_after):
            self._open_restoring(edit.result_after)
            self.panel.status = f"redo: {edit.result_after.name} is back"
            return
        style, style2, mix = edit.before if name == "undo" else edit.after
        from gstyle_core.errors import GStyleError

        self._restoring = True
        try:
            if style:
                self.set_style(style)
            if style2:
                self.set_style(style2, 1, mix)
            elif self.panel.style2_path:
                self.remove_second_style()
            if self.bridge is not None:
                self.start_engine(action=f"{name} of a painting")
        except GStyleError as exc:
            self.panel.status = f"{name}: {exc}"
            return
        finally:
            self._restoring = False
        self.panel.status = f"{name}: {edit.describe()}"
