"""The studio's file browser model (``app/file_browser.py``) and the choice between it and a native dialog
(``app.open_files.native_dialog``): no ImGui, no GL."""

import json
import os

import pytest

from app.file_browser import MAX_RECENT, Entry, FileBrowser, has_suffix, load_recent, save_recent, with_recent
from app.open_files import DIALOG_ENV, FILE_KINDS, NO_PROGRAM, native_dialog
from gstyle_core.images import IMAGE_SUFFIXES
from gstyle_core.io import SCENE_SUFFIXES


@pytest.fixture
def tree(tmp_path):
    """scenes/ with every scene kind and some other files, paintings/, a hidden folder and file."""
    scenes = tmp_path / "scenes"
    (scenes / "sub").mkdir(parents=True)
    for name in ("b.ply", "a.compressed.ply", "c.SPLAT", "d.spz", "notes.txt", "picture.png", ".hidden.ply"):
        (scenes / name).write_bytes(b"x")
    (scenes / ".git").mkdir()
    (tmp_path / "paintings").mkdir()
    (tmp_path / "paintings" / "wave.JPG").write_bytes(b"x")
    return tmp_path


def test_the_dialogs_offer_the_readers_suffixes_compressed_ply_included():
    assert FILE_KINDS["open_scene"].suffixes == (*SCENE_SUFFIXES, "batch.csv")  # a gstyle batch's table: its takes
    assert ".compressed.ply" in SCENE_SUFFIXES
    assert FILE_KINDS["open_style"].suffixes == FILE_KINDS["open_style2"].suffixes == IMAGE_SUFFIXES
    assert has_suffix("x.COMPRESSED.PLY", [".compressed.ply"]) and not has_suffix("x.ply", [".compressed.ply"])
    assert not has_suffix("ply", [".ply"]) and has_suffix("a.b.spz", SCENE_SUFFIXES)


def test_listing_shows_folders_then_accepted_files_sorted_without_hidden_ones(tree):
    browser = FileBrowser("Open scene", SCENE_SUFFIXES, folder=tree / "scenes")
    assert browser.entries() == [Entry("sub", True), Entry("a.compressed.ply", False), Entry("b.ply", False),
                                 Entry("c.SPLAT", False), Entry("d.spz", False)]
    browser.show_all = True
    browser.refresh()
    assert [e.name for e in browser.entries() if not e.is_dir] == ["a.compressed.ply", "b.ply", "c.SPLAT", "d.spz",
                                                                  "notes.txt", "picture.png"]
    browser.show_hidden = True
    browser.refresh()
    assert Entry(".git", True) in browser.entries() and Entry(".hidden.ply", False) in browser.entries()
    assert browser.filter_label() == "*.ply *.compressed.ply *.splat *.spz *.sog *meta.json"


def test_up_enter_go_and_typed_paths(tree):
    browser = FileBrowser("Open style image", IMAGE_SUFFIXES, folder=tree / "scenes")
    assert browser.enter("sub") and browser.folder == (tree / "scenes" / "sub").resolve()
    assert browser.up() and browser.up() and browser.folder == tree.resolve()
    assert not browser.enter("nope") and "not a folder" in browser.error and browser.folder == tree.resolve()
    assert browser.submit("paintings") is None and browser.folder == (tree / "paintings").resolve()  # a folder: go
    assert browser.error == "" and [e.name for e in browser.entries()] == ["wave.JPG"]
    assert browser.submit("missing.png") is None and browser.error.startswith("no such file: ")
    assert browser.submit("") is None and browser.error == "choose a file (or type its path)"
    browser.select("wave.JPG")
    assert browser.path_text == "wave.JPG" and browser.submit() == (tree / "paintings" / "wave.JPG").resolve()
    chosen = browser.submit(str(tree / "scenes" / "b.ply"))  # an absolute path anywhere, whatever its suffix
    assert chosen == (tree / "scenes" / "b.ply").resolve()
    assert browser.recent[:2] == [(tree / "scenes").resolve(), (tree / "paintings").resolve()]


def test_the_root_has_no_parent_and_an_unlistable_start_falls_back_to_the_working_folder(tmp_path):
    root = FileBrowser("t", SCENE_SUFFIXES, folder=os.sep)
    assert not root.up() and str(root.folder) == os.sep
    missing = FileBrowser("t", SCENE_SUFFIXES, folder=tmp_path / "gone")
    assert missing.folder == type(missing.folder).cwd().resolve()


def test_recent_folders_come_first_once_and_at_most_eight(tmp_path):
    recent = []
    for i in range(MAX_RECENT + 3):
        recent = with_recent(recent, tmp_path / str(i))
    recent = with_recent(recent, tmp_path / "5")
    assert len(recent) == MAX_RECENT and recent[0] == (tmp_path / "5").resolve()
    assert recent.count((tmp_path / "5").resolve()) == 1
    browser = FileBrowser("t", SCENE_SUFFIXES, recent=[tmp_path])
    assert browser.folder == tmp_path.resolve()  # starts in the most recent folder


def test_recent_folders_on_disk_survive_bad_files_and_drop_vanished_folders(tmp_path):
    file = tmp_path / "cache" / "recent_folders.json"
    assert load_recent(file) == []
    keep = tmp_path / "keep"
    keep.mkdir()
    assert save_recent(file, [keep, tmp_path / "vanished"])
    assert json.loads(file.read_text()) == [str(keep), str(tmp_path / "vanished")]
    assert load_recent(file) == [keep]
    for junk in ("{not json", '{"a": 1}', "[1, 2]"):
        file.write_text(junk)
        assert load_recent(file) == []
    blocked = tmp_path / "blocked"
    blocked.write_text("a file where the folder should be")
    assert not save_recent(blocked / "recent.json", [keep])


@pytest.mark.parametrize("platform", ["win32", "darwin"])
def test_windows_and_macos_always_have_a_native_dialog(platform):
    assert native_dialog(platform, which=lambda _: None, env={}) == ("system", "")


def test_linux_needs_a_dialog_program_and_the_environment_can_ask_for_the_studio_browser():
    assert native_dialog("linux", which=lambda _: None, env={}) == (None, NO_PROGRAM)
    assert native_dialog("linux", which=lambda p: f"/usr/bin/{p}" if p == "qarma" else None, env={})[0] == "qarma"
    has_all = {"zenity", "kdialog"}
    assert native_dialog("linux", which=lambda p: p if p in has_all else None, env={})[0] == "zenity"
    assert native_dialog("darwin", which=lambda p: p, env={DIALOG_ENV: " Studio "}) == (None, f"{DIALOG_ENV}=studio")
