"""The studio's painting(s): the painting opened, a second one mixed in with the mix slider, removed; their
thumbnails, the engine config's ``style`` (and ``style_weights``), and a painting choice as an undo step of its own
(``ChoiceEdit``, ``result_undo.py``). ``Paintings`` is a part of ``StudioApp``."""

from __future__ import annotations

from collections.abc import Callable

import moderngl
import numpy as np

from gstyle_core.errors import GStyleError

from .panels import PanelState
from .result_files import ResultInfo


class Paintings:
    """The painting(s) in the panel and their thumbnails' GL textures (owned here). Built with the GL context, the
    panel and ``set_style`` (the engine link's: the config's paintings and their weights)."""

    def __init__(self, ctx: moderngl.Context, panel: PanelState,
                 set_style: Callable[[str | list[str] | None, tuple[float, float] | None], None]) -> None:
        self.ctx, self.panel, self._set_engine_style = ctx, panel, set_style
        self._textures: list[moderngl.Texture | None] = [None, None]  # thumbnails of the first and second style

    def set_style(self, path: str, slot: int = 0, mix: float | None = None) -> None:
        """Use a new style image (``slot`` 0: the painting; 1: a second painting mixed in with the mix slider, at
        ``mix``, by default the slider's value or an even mix): thumbnail in the panel; the caller restarts the
        engine with it."""
        from gstyle_core.images import load_style_image

        rgb = load_style_image(path)
        thumb = np.ascontiguousarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8))
        self._release_texture(slot)
        h, w = thumb.shape[:2]
        texture = self.ctx.texture((w, h), 3, thumb.tobytes(), alignment=1)
        self._textures[slot] = texture
        if slot == 0:
            self.panel.style_texture, self.panel.style_size, self.panel.style_path = texture.glo, (w, h), str(path)
        else:
            self.panel.style2_texture, self.panel.style2_size, self.panel.style2_path = texture.glo, (w, h), str(path)
            if mix is not None:
                self.panel.params["style_mix"] = float(mix)
            elif not self.panel.params.get("style_mix"):  # a new second painting starts at an even mix
                self.panel.params["style_mix"] = 0.5
        self.update_style_config()

    def remove_second_style(self) -> None:
        """Back to one painting (the caller restarts the engine)."""
        self._release_texture(1)
        self.panel.style2_texture, self.panel.style2_path = None, ""
        self.panel.params["style_mix"] = 0.0
        self.update_style_config()

    def _release_texture(self, slot: int) -> None:
        texture = self._textures[slot]
        if texture is not None:
            texture.release()
            self._textures[slot] = None

    def update_style_config(self) -> None:
        """The engine config's style: the painting's path, or both paths with their weights (the mix slider)."""
        p = self.panel
        if p.style2_path and p.style_path:
            mix = float(p.params.get("style_mix", 0.5))
            self._set_engine_style([p.style_path, p.style2_path], (1.0 - mix, mix))
        else:
            self._set_engine_style(p.style_path or None, None)

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

    def show_result(self, info: ResultInfo | None) -> None:
        """A stylized result is shown: show the painting(s) it was made after (a second one at the result's mix),
        when their files are found and read (else the paintings shown stay; the result opens all the same). These,
        or the ones the artist opens while it is on show, are what *Restart from the original* stylizes with."""
        if info is None or not info.styles:
            return
        second = str(info.styles[1]) if len(info.styles) > 1 else ""
        mix = float(info.params.get("style_mix", 0.5)) if second else 0.0
        try:
            self.put_paintings((str(info.styles[0]), second, mix))
        except GStyleError:
            pass
