"""The studio's painting(s): the painting opened, a second one mixed in with the mix slider, removed; their
thumbnails, the engine config's ``style`` (and ``style_weights``), and a painting choice as an undo step of its own
(``ChoiceEdit``, ``result_undo.py``). ``Paintings`` is a mixin of ``StudioApp``."""

from __future__ import annotations

import numpy as np


class Paintings:
    """``StudioApp``'s painting(s)."""

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

    def painting_state(self) -> tuple[str, str, float]:
        """The painting(s) chosen now: (painting, second painting or "", mix)."""
        p = self.panel
        return p.style_path or "", p.style2_path or "", float(p.params.get("style_mix", 0.0))

    def put_paintings(self, state: tuple[str, str, float]) -> None:
        """Choose ``state``'s painting(s) and mix (``painting_state``); ``GStyleError`` for a file that no longer
        reads. The caller restarts the engine."""
        style, style2, mix = state
        if style:
            self.set_style(style)
        if style2:
            self.set_style(style2, 1, mix)
        elif self.panel.style2_path:
            self.remove_second_style()
