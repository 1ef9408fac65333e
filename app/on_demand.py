"""Render on demand: the studio draws frames only while something changes, and sleeps in the window system's
event wait otherwise (a still studio costs next to no CPU: issue #27 item 7).

Something changes when the window gets an input or window event (``EventCounter``, chained in front of ImGui's
callbacks), a key or mouse button is held (flying, dragging), the engine sends news, the view is still building
its full-resolution image, or a video, a dialog or a screenshot is pending (``StudioApp.busy``). After the last
change frames go on for ``settle`` seconds (ImGui's hover tooltips and fades), then the loop waits for events,
waking every ``poll`` seconds to ask the engine for news."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

SETTLE_S = 1.0
POLL_S = 0.25


@dataclass
class EventCounter:
    """Counts the window's events and tracks held keys and buttons (glfw callbacks, installed before ImGui's
    backend so that it chains to them)."""

    events: int = 0
    held: set[tuple[str, int]] = field(default_factory=set)

    def install(self, glfw: Any, handle: Any, on_key: Callable[[int, int, int, int], None] | None = None) -> None:
        """Set the counting callbacks on window ``handle`` (call before ``glfw_init_for_opengl``); ``on_key(key,
        scancode, action, mods)`` also gets every key event (the studio's shortcuts, ``app/keys.py``)."""
        def bump(*_args: Any) -> None:
            self.events += 1

        def key(_w: Any, key: int, scancode: int, action: int, mods: int) -> None:
            self._hold(("key", key), action)
            if on_key is not None:
                on_key(key, scancode, action, mods)

        def button(_w: Any, button: int, action: int, _mods: int) -> None:
            self._hold(("button", button), action)

        self._callbacks = [bump, key, button]  # keep the ctypes thunks alive
        glfw.set_key_callback(handle, key)
        glfw.set_mouse_button_callback(handle, button)
        for setter in (glfw.set_cursor_pos_callback, glfw.set_scroll_callback, glfw.set_char_callback,
                       glfw.set_window_size_callback, glfw.set_framebuffer_size_callback,
                       glfw.set_window_focus_callback, glfw.set_window_refresh_callback,
                       glfw.set_cursor_enter_callback, glfw.set_window_iconify_callback):
            setter(handle, bump)

    def _hold(self, what: tuple[str, int], action: int) -> None:
        self.events += 1
        if action == 0:  # GLFW_RELEASE
            self.held.discard(what)
        else:
            self.held.add(what)


class OnDemand:
    """Decides, each turn of the loop, whether to draw a frame or wait for events."""

    def __init__(self, counter: EventCounter, busy: Callable[[], bool], wait: Callable[[float], None],
                 settle: float = SETTLE_S, poll: float = POLL_S, clock: Callable[[], float] = time.monotonic) -> None:
        self.counter, self.busy, self.wait = counter, busy, wait
        self.settle, self.poll, self.clock = settle, poll, clock
        self._seen = -1
        self._last_change = clock()
        self.waits = 0  # turns spent waiting (tests, bench)

    def should_draw(self) -> bool:
        """True: draw a frame now. False: nothing changed for ``settle`` s; one event wait (up to ``poll`` s) was
        spent, call again."""
        now = self.clock()
        if self._changed():
            self._last_change = now
            return True
        if now - self._last_change < self.settle:
            return True
        self.wait(self.poll)
        self.waits += 1
        if self._changed():
            self._last_change = self.clock()
            return True
        return False

    def _changed(self) -> bool:
        events = self.counter.events
        fresh = events != self._seen
        self._seen = events
        return fresh or bool(self.counter.held) or self.busy()
