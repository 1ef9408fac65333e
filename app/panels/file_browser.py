"""The studio's own file browser window (model: ``app/file_browser.FileBrowser``), for desktops without a native
file dialog: recent folders, up, the folder's subfolders and accepted files, a path field (Enter opens what is typed),
"all files", Open and Cancel. Navigation changes the browser; the answer is a ``browser_open`` or
``browser_cancel`` command."""

from __future__ import annotations

from typing import Any

from imgui_bundle import imgui

from .state import Command
from .widgets import button, tooltip

BROWSER_SIZE = (600.0, 460.0)
ERROR_COLOUR = (1.0, 0.45, 0.4, 1.0)
PATH_HINT = "type a file or folder path; Enter opens it"


def file_browser_window(browser: Any, out: list[Command]) -> None:
    """Draw the browser window (centred when it appears); its close box, Escape and Cancel cancel."""
    viewport = imgui.get_main_viewport()
    imgui.set_next_window_pos(viewport.get_center(), imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    imgui.set_next_window_size(imgui.ImVec2(*BROWSER_SIZE), imgui.Cond_.appearing)
    if browser.focus_path:  # just opened, or Enter was pressed: in front, typing goes to its path field
        imgui.set_next_window_focus()
    shown, keep_open = imgui.begin(f"{browser.title}###file_browser", True)
    if shown:
        if browser.note:
            imgui.text_wrapped(browser.note)
        _folder_row(browser)
        _path_field(browser, out)
        _listing(browser, out)
        _footer(browser, out)
        focused = imgui.is_window_focused(imgui.FocusedFlags_.root_and_child_windows)
        if focused and imgui.is_key_pressed(imgui.Key.escape, False):
            keep_open = False
    imgui.end()
    if not keep_open:
        out.append(Command("browser_cancel"))


def _folder_row(browser: Any) -> None:
    """Up, the recent folders, and where the browser is."""
    if button("Up", "The folder above this one."):
        browser.up()
    if browser.recent:
        imgui.same_line()
        imgui.set_next_item_width(220)
        if imgui.begin_combo("##recent", "Recent folders"):
            for folder in list(browser.recent):
                if imgui.selectable(str(folder), folder == browser.folder)[0]:
                    browser.go(folder)
            imgui.end_combo()
        tooltip("Folders files were opened from before.")
    imgui.text_wrapped(f"Folder: {browser.folder}")


def _path_field(browser: Any, out: list[Command]) -> None:
    """The path field; it has the keyboard focus when the browser opens and after each Enter."""
    if browser.focus_path:
        imgui.set_keyboard_focus_here()
        browser.focus_path = False
    imgui.set_next_item_width(-1)
    entered, browser.path_text = imgui.input_text_with_hint("##path", PATH_HINT, browser.path_text,
                                                            imgui.InputTextFlags_.enter_returns_true)
    tooltip("A file name in this folder, or a whole path (~ for home). A folder's path goes there.")
    if entered:
        _submit(browser, out)
        browser.focus_path = True


def _listing(browser: Any, out: list[Command]) -> None:
    """Subfolders (click: go in) and accepted files (click: select; double-click: open). The second click of a
    double-click only opens the file its first click selected: after the first went into a folder it lands on
    whatever is there now, so it does nothing more than select."""
    footer = imgui.get_frame_height_with_spacing() * 2 + imgui.get_text_line_height_with_spacing()
    imgui.begin_child("##entries", imgui.ImVec2(0, -footer), imgui.ChildFlags_.borders)
    entries = browser.entries()
    for entry in entries:
        label = entry.name.replace("##", "# #") + ("/" if entry.is_dir else "")
        clicked = imgui.selectable(label, entry.name == browser.selected,
                                   imgui.SelectableFlags_.allow_double_click)[0]
        if not clicked:
            continue
        double = imgui.is_mouse_double_clicked(0)
        if entry.is_dir:
            if not double:
                browser.enter(entry.name)
        elif double and entry.name == browser.selected:
            _submit(browser, out)
        else:
            browser.select(entry.name)
        break
    if not entries:
        imgui.text_disabled("(no folders or matching files here)")
    imgui.end_child()


def _footer(browser: Any, out: list[Command]) -> None:
    """The filter and "all files", why the last action did nothing, Open and Cancel."""
    imgui.text_disabled(f"Files: {browser.filter_label()}")
    imgui.same_line()
    changed, browser.show_all = imgui.checkbox("all files", browser.show_all)
    tooltip("List every file, not only those the studio opens.")
    if changed:
        browser.refresh()
    imgui.text_colored(imgui.ImVec4(*ERROR_COLOUR), browser.error)  # one line, empty when all is well
    if browser.saving and button("Save", "Save under the name typed above (in this folder, unless it is a path; "
                                         ".ply when it names no format)."):
        _submit(browser, out)
    elif not browser.saving and button("Open", "Open the selected file, or the path typed above."):
        _submit(browser, out)
    imgui.same_line()
    if button("Cancel", "Close the browser without opening anything (Escape)."):
        out.append(Command("browser_cancel"))


def _submit(browser: Any, out: list[Command]) -> None:
    chosen = browser.submit()
    if chosen is not None:
        out.append(Command("browser_open", {"path": str(chosen)}))
