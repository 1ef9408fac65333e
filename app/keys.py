"""Key presses as the window system reports them, each with the modifiers held at that moment: what the studio's
shortcuts act on (issue #27 item 8).

Shortcuts must not read the keyboard's state once a frame. A tap of Ctrl+S can fall inside one slow frame (the
engine busy on 2 cores), and keyboards and xdotool often let go of Ctrl before S: polled once a frame, ImGui then
sees S pressed with Ctrl already up, and the export is lost. glfw's key callback gives each press with its
modifiers (``KeyPresses.on_key``); the studio takes the presses queued since the last frame (``take``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

# glfw's values (glfw/glfw3.h); this module needs no glfw import, so panels and tests use it freely.
RELEASE, PRESS = 0, 1
MOD_SHIFT, MOD_CONTROL, MOD_ALT, MOD_SUPER = 0x1, 0x2, 0x4, 0x8
SPECIAL_KEYS = {32: "space", 256: "escape", 257: "enter", 258: "tab", 259: "backspace", 335: "enter"}
SPECIAL_KEYS.update({290 + i: f"f{i + 1}" for i in range(12)})  # GLFW_KEY_F1 = 290


@dataclass(frozen=True)
class KeyPress:
    """One key going down: its name ("s", "2", "f12", "space", "escape") and the modifiers held with it."""

    name: str
    ctrl: bool = False
    shift: bool = False
    alt: bool = False
    super: bool = False

    @property
    def plain(self) -> bool:
        """No Ctrl, Alt or Super held (Shift may be)."""
        return not (self.ctrl or self.alt or self.super)


def key_name(key: int, layout_name: str | None = None) -> str | None:
    """The name of glfw key code ``key``: ``layout_name`` (glfw's name of the key in the keyboard layout, e.g. "z"
    for the key in the place of US "y" on a German keyboard) when it is one letter or digit, else the US name of the
    key code; None for keys no shortcut uses. The keypad's keys have no name (the number row snaps to cameras)."""
    if key < 256 and layout_name and len(layout_name) == 1 and layout_name.isascii() and layout_name.isalnum():
        return layout_name.lower()
    if 48 <= key <= 57 or 65 <= key <= 90:  # GLFW_KEY_0..9, GLFW_KEY_A..Z (ASCII)
        return chr(key).lower()
    return SPECIAL_KEYS.get(key)


@dataclass
class KeyPresses:
    """The presses since the studio last took them, and the keys held down since they were pressed together with
    Ctrl, Alt or Super (``chorded``: the S of Ctrl+S does not fly the camera back while it is still down)."""

    layout: Callable[[int, int], str | None] | None = None  # glfw.get_key_name: a key's name in the layout
    queue: list[KeyPress] = field(default_factory=list)
    chorded: set[str] = field(default_factory=set)

    def on_key(self, key: int, scancode: int, action: int, mods: int) -> None:
        """glfw's key callback (without the window argument): queue a press with the modifiers glfw reports."""
        name = key_name(key, self.layout(key, scancode) if self.layout is not None else None)
        if name is None:
            return
        if action == RELEASE:
            self.chorded.discard(name)
            return
        if action != PRESS:  # GLFW_REPEAT: shortcuts act once per press
            return
        self.press(name, ctrl=bool(mods & MOD_CONTROL), shift=bool(mods & MOD_SHIFT), alt=bool(mods & MOD_ALT),
                   super_=bool(mods & MOD_SUPER))

    def press(self, name: str, *, ctrl: bool = False, shift: bool = False, alt: bool = False,
              super_: bool = False) -> None:
        """Queue one press (also how headless tests type a shortcut)."""
        press = KeyPress(name, ctrl, shift, alt, super_)
        self.queue.append(press)
        if not press.plain:
            self.chorded.add(name)

    def take(self) -> list[KeyPress]:
        """The presses queued since the last call, oldest first; the queue is emptied."""
        presses, self.queue = self.queue, []
        return presses
