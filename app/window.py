"""A glfw window with a GL context, moderngl attached and the native ImGui backends (imgui_bundle API A).

Headless: glfw's NULL platform with an EGL context (no X server needed; imgui_bundle's libglfw 3.5 can do it,
so ``imgui_bundle`` is imported before ``glfw``).
"""

from __future__ import annotations

import ctypes
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

# isort: off
from imgui_bundle import imgui  # first: it points pyglfw at its own libglfw 3.5 (NULL + EGL needs it)
import glfw
import moderngl
# isort: on

from gstyle_core.errors import GStyleError

from .keys import KeyPresses
from .on_demand import EventCounter
from .window_size import DEFAULT_SIZE, initial_size, remember_size, remembered_size


class DisplayUnavailableError(GStyleError):
    """No window can be opened (no display server, or glfw failed to start)."""


def display_available() -> bool:
    """True if an X11 or Wayland display is configured."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


@dataclass
class Window:
    """An open window: glfw handle, moderngl context, ImGui context."""

    handle: Any
    ctx: moderngl.Context
    headless: bool
    counter: EventCounter = field(default_factory=EventCounter)  # its events (render on demand, app/on_demand.py)
    keys: KeyPresses = field(default_factory=KeyPresses)  # its key presses with their modifiers (app/keys.py)
    remember: bool = False  # keep its size for the next session when it closes (its size was not asked for)

    @property
    def framebuffer_size(self) -> tuple[int, int]:
        """Framebuffer size in pixels."""
        w, h = glfw.get_framebuffer_size(self.handle)
        return max(int(w), 1), max(int(h), 1)

    def should_close(self) -> bool:
        return bool(glfw.window_should_close(self.handle))

    def begin_frame(self) -> None:
        """Poll events and start an ImGui frame."""
        glfw.poll_events()
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        imgui.new_frame()

    def end_frame(self, swap: bool = True) -> None:
        """Render ImGui into the default framebuffer and (optionally) swap buffers."""
        imgui.render()
        self.ctx.screen.use()
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
        if swap:
            glfw.swap_buffers(self.handle)

    def draw(self, frame: Callable[[moderngl.Framebuffer], Any]) -> moderngl.Framebuffer:
        """One whole frame without swapping (headless runs and benches): ImGui frame, ``frame(screen)`` into the
        full-size default framebuffer, ImGui on top, GL finished. Returns the screen (to read back)."""
        self.begin_frame()
        screen = self.ctx.screen
        screen.viewport = (0, 0, *self.framebuffer_size)
        screen.use()
        frame(screen)
        self.end_frame(swap=False)
        self.ctx.finish()
        return screen

    def close(self) -> None:
        """Shut down ImGui backends and glfw (a window whose size was not asked for keeps its size for next time)."""
        if self.remember:
            remember_size(glfw.get_window_size(self.handle))
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        try:
            from imgui_bundle import implot

            implot.destroy_context()
        except ImportError:
            pass
        imgui.destroy_context()
        glfw.destroy_window(self.handle)
        glfw.terminate()


def open_window(width: int | None = None, height: int | None = None, title: str = "G-Style Studio",
                headless: bool = False) -> Window:
    """Create the window, the GL 3.3+ core context, moderngl and ImGui. Raises DisplayUnavailableError. Without a
    size: the one kept from the last session, else 80 % of the screen (``window_size.py``; headless: 1280 x 800)."""
    if not headless and not display_available():
        raise DisplayUnavailableError("no display (DISPLAY/WAYLAND_DISPLAY unset)")
    # init hints outlive glfw.terminate(): set the platform every time
    glfw.init_hint(glfw.PLATFORM, glfw.PLATFORM_NULL if headless else glfw.ANY_PLATFORM)
    if not glfw.init():
        raise DisplayUnavailableError("glfw could not initialise a window system")
    glfw.default_window_hints()
    if headless:
        glfw.window_hint(glfw.CONTEXT_CREATION_API, glfw.EGL_CONTEXT_API)
        glfw.window_hint(glfw.VISIBLE, glfw.FALSE)
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, glfw.TRUE)
    asked = (int(width), int(height)) if width is not None and height is not None else None
    if headless:
        size = asked or DEFAULT_SIZE
    else:
        size = initial_size(asked, remembered_size(), _workarea())
    handle = glfw.create_window(size[0], size[1], title, None, None)
    if not handle:
        glfw.terminate()
        raise DisplayUnavailableError("glfw could not create an OpenGL 3.3 window")
    glfw.make_context_current(handle)
    glfw.swap_interval(0)  # the app caps its own frame rate
    ctx = _attach_moderngl()
    imgui.create_context()
    try:
        from imgui_bundle import implot

        implot.create_context()
    except ImportError:
        pass
    imgui.get_io().set_ini_filename("")
    counter, keys = EventCounter(), KeyPresses(layout=_layout_key_name)
    counter.install(glfw, handle, keys.on_key)  # first: ImGui's backend chains its callbacks to these
    imgui.backends.glfw_init_for_opengl(ctypes.cast(handle, ctypes.c_void_p).value, True)
    imgui.backends.opengl3_init("#version 330")
    return Window(handle, ctx, headless, counter, keys, remember=asked is None and not headless)


def _workarea() -> tuple[int, int] | None:
    """Width and height of the primary screen less its task bars (None when glfw cannot tell)."""
    try:
        monitor = glfw.get_primary_monitor()
        if not monitor:
            return None
        _, _, w, h = glfw.get_monitor_workarea(monitor)
        return (int(w), int(h)) if w > 0 and h > 0 else None
    except Exception:  # noqa: BLE001 - glfw reports errors as exceptions or warnings, depending on its settings
        return None


def _layout_key_name(key: int, scancode: int) -> str | None:
    """glfw's name of a printable key in the keyboard layout (None for the others, or when glfw cannot tell)."""
    try:
        return glfw.get_key_name(key, scancode)
    except Exception:  # noqa: BLE001 - glfw reports errors as exceptions or warnings, depending on its settings
        return None


def _attach_moderngl() -> moderngl.Context:
    """Attach moderngl to the current context (a stale standalone default context would confuse create_context)."""
    try:
        return moderngl.create_context()
    except Exception:  # noqa: BLE001 - fall back to the explicit attach path (gl-stack.md pitfall 3)
        moderngl.init_context()
        return moderngl.get_context()
