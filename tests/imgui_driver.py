"""Drive the studio's ImGui panel headless: record every widget it draws (id path, rectangle, tooltip, texts) and
click widgets by their path with injected mouse events."""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from imgui_bundle import imgui

WIDGETS = ("button", "small_button", "checkbox", "radio_button", "slider_float", "begin_combo", "selectable",
           "collapsing_header", "input_text_with_hint", "drag_float3")


@dataclass
class Widget:
    """One drawn widget: ``path`` is the pushed ids and its label joined by "/" (e.g. "lambda_nnfm/reset")."""

    kind: str
    path: str
    rect: tuple[float, float, float, float]
    tooltip: str | None = None

    def point(self, fx: float = 0.5) -> tuple[float, float]:
        """A point inside: ``fx`` of the way across, half way down."""
        x0, y0, x1, y1 = self.rect
        return x0 + fx * (x1 - x0), 0.5 * (y0 + y1)


class Recorder:
    """Stands in for the ``imgui`` module of ``app.panels``' modules: calls the real one and records what was drawn."""

    def __init__(self) -> None:
        self.widgets: list[Widget] = []
        self.texts: list[str] = []
        self._ids: list[str] = []

    def __getattr__(self, name: str) -> Any:
        attr = getattr(imgui, name)
        return self._recording(name, attr) if name in WIDGETS else attr

    def _recording(self, kind: str, fn: Callable) -> Callable:
        def call(label, *args, **kw):
            result = fn(label, *args, **kw)
            lo, hi = imgui.get_item_rect_min(), imgui.get_item_rect_max()
            right = hi.x
            if kind in ("slider_float", "drag_float3"):  # the item's rectangle includes the label right of its frame
                shown = label.split("##")[0]
                if shown:
                    right -= imgui.calc_text_size(shown).x + imgui.get_style().item_inner_spacing.x
            self.widgets.append(Widget(kind, "/".join([*self._ids, label]), (lo.x, lo.y, right, hi.y)))
            return result

        return call

    def push_id(self, name: str) -> None:
        self._ids.append(str(name))
        imgui.push_id(name)

    def pop_id(self) -> None:
        self._ids.pop()
        imgui.pop_id()

    def text_wrapped(self, text: str) -> None:
        self.texts.append(text)
        imgui.text_wrapped(text)

    def mark_tooltip(self, text: str) -> None:
        """``app.panels.widgets.tooltip`` was called for the last widget."""
        if self.widgets:
            self.widgets[-1].tooltip = text

    def find(self, path: str) -> Widget:
        matches = [w for w in self.widgets if w.path == path]
        assert matches, f"no widget {path!r} drawn; drawn: {[w.path for w in self.widgets]}"
        return matches[-1]


def install(monkeypatch) -> Recorder:
    """Route the ImGui calls of every module of ``app.panels`` (and their tooltip helper) through a new
    ``Recorder``."""
    import app.panels
    from app.panels import widgets

    recorder = Recorder()
    original_tooltip = widgets.tooltip

    def tooltip(text: str) -> None:
        recorder.mark_tooltip(text)
        original_tooltip(text)

    modules = [m for name, m in sys.modules.items() if name.startswith(f"{app.panels.__name__}.")]
    for module in modules:
        if getattr(module, "imgui", None) is imgui:
            monkeypatch.setattr(module, "imgui", recorder)
        if getattr(module, "tooltip", None) is original_tooltip:
            monkeypatch.setattr(module, "tooltip", tooltip)
    return recorder


class PanelDriver:
    """Frames of ``draw`` (returns commands) in a headless window, with injected input."""

    def __init__(self, window, recorder: Recorder, draw: Callable[[], list]) -> None:
        self.window, self.recorder, self.draw = window, recorder, draw

    def frame(self, *events: Callable[[Any], None]) -> list:
        io = imgui.get_io()
        for event in events:
            event(io)
        self.window.begin_frame()
        self.recorder.widgets.clear()
        self.recorder.texts.clear()
        commands = self.draw()
        self.window.end_frame(swap=False)
        return list(commands)

    def click(self, path: str, fx: float = 0.5) -> list:
        """Click the widget at ``path`` (``fx`` across it); the commands of every frame until the release."""
        self.frame()
        x, y = self.recorder.find(path).point(fx)
        commands = self.frame(lambda io: io.add_mouse_pos_event(x, y))
        commands += self.frame(lambda io: io.add_mouse_button_event(0, True))
        commands += self.frame(lambda io: io.add_mouse_button_event(0, False))
        commands += self.frame(lambda io: io.add_mouse_pos_event(-1, -1))
        return commands


def panel_alone(window, monkeypatch, state) -> PanelDriver:
    """A driver that draws the panel alone for ``state``, its set_params commands applied to it as the studio
    does."""
    from app.panels import draw_panel

    recorder = install(monkeypatch)

    def draw():
        commands = draw_panel(state)
        for c in commands:
            if c.name == "set_params":
                state.params.update(c.args)
        return commands

    return PanelDriver(window, recorder, draw)


def studio_driver(window, monkeypatch, app) -> PanelDriver:
    """A driver that draws the whole studio frame (``app.frame``) into the test window."""
    def draw():
        window.ctx.screen.use()
        return app.frame(window.ctx.screen)

    return PanelDriver(window, install(monkeypatch), draw)


def paused_studio_driver(window, monkeypatch, app) -> PanelDriver:
    """Start the studio's engine, wait until it is ready, pause it, and return a driver for the studio frame."""
    app.engine.start()
    assert app.engine.bridge.wait_until(lambda s: s.ready or s.error, 60) and app.engine.bridge.state.error is None
    app.engine.bridge.pause()
    assert app.engine.bridge.wait_until(lambda s: s.paused, 30)
    return studio_driver(window, monkeypatch, app)
