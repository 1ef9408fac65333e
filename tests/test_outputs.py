"""Outputs that never lose work (issue #25): one naming rule for companions, and every writer under a full disk
(ENOSPC), a forbidden folder (EACCES) and a read-only file system (EROFS) through patched writes (``faults``): one
line naming the path and the cause, never a half-written file, the old file kept."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import numpy as np
import pytest
from faults import Faults, listing
from hypothesis import assume, given
from hypothesis import strategies as st
from synthetic import blob_scene

from gstyle_core.atomic import atomic_write_text
from gstyle_core.cli import run
from gstyle_core.errors import GStyleError, OutputWriteError
from gstyle_core.io import load_scene, save_scene
from gstyle_core.outputs import (
    FORMAT_SUFFIXES,
    OutputGroup,
    check_writable,
    companion,
    output_base,
    refuse_overwrites,
    write_cause,
)

CODES = {errno.ENOSPC: "no space left on the device", errno.EACCES: "permission denied",
         errno.EROFS: "read-only file system"}
TAILS = (".json", "_before.png", "_after.png")


# ====================================================================== the naming rule
@pytest.mark.parametrize("name, summary", [
    ("seal0.5.ply", "seal0.5.json"), ("v1.0.ply", "v1.0.json"), ("v1.5.ply", "v1.5.json"),
    ("web.compressed.ply", "web.json"), ("WEB.Compressed.PLY", "WEB.json"), ("a.b.c.spz", "a.b.c.json"),
    ("my scene 2.splat", "my scene 2.json"), ("étude №1 · 0.5.ply", "étude №1 · 0.5.json"),
    ("turn.table.mp4", "turn.table.json"), ("loop.GIF", "loop.json"), ("no_suffix", "no_suffix.json"),
    ("notes.txt", "notes.txt.json"), (".ply", ".ply.json"), ("..ply", "..ply.json"), (".compressed.ply",
                                                                                      ".compressed.ply.json"),
    ("x.compressed", "x.compressed.json"), ("x.ply.ply", "x.ply.json"),
])
def test_companions_keep_the_whole_name_but_its_format_suffix(name, summary):
    assert companion(Path("out") / name, ".json") == Path("out") / summary
    assert companion(name, "_before.png").name == summary[: -len(".json")] + "_before.png"


NAME_CHARS = st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="/\\\0")


@given(base=st.text(NAME_CHARS, min_size=1, max_size=30), suffix=st.sampled_from(FORMAT_SUFFIXES),
       upper=st.booleans(), tail=st.sampled_from(TAILS))
def test_companion_names_are_the_output_name_minus_its_format_suffix(base, suffix, upper, tail):
    assume(base not in (".", "..") and not (base + suffix).lower().endswith(".compressed.ply.ply"))
    assume(not (suffix == ".ply" and base.lower().endswith(".compressed")))  # that name is a .compressed.ply
    name = base + (suffix.upper() if upper else suffix)
    out = Path("some dir") / name
    assert output_base(out) == Path("some dir") / base
    assert companion(out, tail) == Path("some dir") / (base + tail)  # never cut at an inner dot
    assert companion(out, tail) != out


@given(a=st.text(NAME_CHARS, min_size=1, max_size=12), b=st.text(NAME_CHARS, min_size=1, max_size=12),
       suffix=st.sampled_from((".ply", ".spz", ".splat")))
def test_different_outputs_never_share_a_companion(a, b, suffix):
    assume(a != b and {a, b}.isdisjoint({".", ".."}))
    assume(not any(x.lower().endswith(".compressed") for x in (a, b)))
    assert companion(a + suffix, ".json") != companion(b + suffix, ".json")


def test_names_the_studio_picks_never_meet_an_earlier_output_or_summary(tmp_path):
    from app.video_job import turntable_path
    from gstyle_core.outputs import unused_name

    stamped = tmp_path / "stylized_0101_120000.compressed.ply"
    assert unused_name(stamped, (".json",)) == stamped
    (tmp_path / "stylized_0101_120000.json").write_text("{}")  # a .ply exported in the same second
    assert unused_name(stamped, (".json",)) == tmp_path / "stylized_0101_120000_2.compressed.ply"
    (tmp_path / "turntable_x").mkdir()
    assert turntable_path(tmp_path, "png frames", "x") == tmp_path / "turntable_x_2"
    assert turntable_path(tmp_path, "mp4", "x") == tmp_path / "turntable_x.mp4"


def test_existing_companions_are_refused_without_force_and_inputs_always(tmp_path):
    out = tmp_path / "v1.0.ply"
    files = [out, *(companion(out, t) for t in TAILS)]
    refuse_overwrites(files, force=False)  # nothing there yet
    companion(out, ".json").write_text("{}")
    with pytest.raises(GStyleError, match=r"v1\.0\.json exists; pass --force to overwrite it"):
        refuse_overwrites(files, force=False)
    out.write_bytes(b"old")
    with pytest.raises(GStyleError, match=r"v1\.0\.ply, .*v1\.0\.json exist; pass --force to overwrite them"):
        refuse_overwrites(files, force=False)
    refuse_overwrites(files, force=True)
    with pytest.raises(GStyleError, match="refusing to overwrite the input file"):
        refuse_overwrites(files, force=True, inputs=[companion(out, ".json")])


# ====================================================================== every writer under a failing disk
def _ply(path):
    save_scene(blob_scene(40, seed=3), path)


def _png(path):
    from gstyle_core.scene_images import save_png

    save_png(path, np.random.default_rng(0).random((24, 32, 3)))


def _json(path):
    atomic_write_text(path, json.dumps({"a": list(range(100))}))


def _frames(path):
    from gstyle_core.video import write_frames

    write_frames([np.full((16, 16, 3), v, np.float32) for v in (0.1, 0.5, 0.9)], path, 10)


def _checkpoint(path):
    from gstyle_core.engine.checkpoint import save_checkpoint

    save_checkpoint(path, {"phase": "stylize", "global_step": 3, "c_s": np.ones((50, 3))}, {"kind": "stylize"})


def _takes(path):
    """The studio's shelf: a take added while takes.json cannot be saved stays for the session; the failure is
    kept as one line for the panel (returned)."""
    from app.takes import TakeShelf

    take = path.parent.parent / "t.ply"  # the take's file itself lies elsewhere
    take.write_bytes(b"x")
    shelf = TakeShelf(path.parent)
    shelf.add(take, 5)
    assert [t.path for t in shelf.takes][:1] == [str(take)]
    return shelf.pop_write_error()


WRITERS = {"scene.ply": _ply, "scene.splat": _ply, "scene.spz": _ply, "scene.compressed.ply": _ply,
           "picture.png": _png, "summary.json": _json, "turntable.gif": _frames, "frames": _frames,
           "run.ckpt": _checkpoint, "takes.json": _takes}


@pytest.mark.parametrize("code", list(CODES))
@pytest.mark.parametrize("name", list(WRITERS))
def test_a_failing_write_is_one_line_and_leaves_the_old_file_whole(tmp_path, monkeypatch, name, code):
    folder = tmp_path / "out"
    WRITERS[name](folder / name)  # an earlier output, complete
    before = {p: (folder / p).read_bytes() for p in listing(folder) if (folder / p).is_file()}
    faults = Faults(monkeypatch)
    faults.arm(folder, code)
    try:
        message = WRITERS[name](folder / name)  # (the takes shelf returns its failure)
    except OutputWriteError as exc:
        message = str(exc)
        assert exc.errno == code and isinstance(exc, OSError)
    assert faults.hits, "the fault was never reached"
    assert message and message.startswith(f"cannot write {folder / name}") and CODES[code] in message, message
    assert "\n" not in message
    faults.disarm()
    assert {p: (folder / p).read_bytes() for p in listing(folder) if (folder / p).is_file()} == before
    WRITERS[name](folder / name)  # once the disk has room again, the same call succeeds


FAKE_FFMPEG = """#!{python}
import os, sys
out = sys.argv[-1]
sys.stdin.buffer.read(1000)  # takes a frame or so, writes the start of the file, then fails as ffmpeg does
with open(out, "wb") as fh:
    fh.write(b"\\0\\0\\0\\x18ftypisom")
sys.stderr.write("[out#0/mp4 @ 0x55] Error closing file: {reason}\\n")
sys.exit(1)
"""


@pytest.mark.parametrize("code", list(CODES))
def test_mp4_that_ffmpeg_cannot_finish_leaves_nothing(tmp_path, monkeypatch, capfd, code):
    """ffmpeg writes the MP4 itself; a full disk often shows only when it closes the file: its exit status and its
    words (captured, not printed) make the one line, and its partial file is never renamed into place."""
    import os
    import sys

    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    from gstyle_core.video import write_frames

    exe = tmp_path / "ffmpeg"
    exe.write_text(FAKE_FFMPEG.format(python=sys.executable, reason=os.strerror(code)))
    exe.chmod(0o755)
    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", lambda: str(exe))
    out_dir = tmp_path / "videos"
    with pytest.raises(OutputWriteError) as caught:
        write_frames([np.zeros((64, 64, 3), np.float32)] * 5, out_dir / "spin.v2.mp4", 10)
    assert str(caught.value) == f"cannot write {out_dir / 'spin.v2.mp4'}: {CODES[code]}"
    assert listing(out_dir) == [] and "Error closing" not in capfd.readouterr().err


def test_causes_without_an_errno_and_a_directory_in_the_way(tmp_path):
    assert write_cause(OSError("ffmpeg said: No space left on device")) == (CODES[errno.ENOSPC], errno.ENOSPC)
    assert write_cause(OSError("weird\nsecond line")) == ("weird", None)
    (tmp_path / "s.ply").mkdir()
    with pytest.raises(OutputWriteError, match=r"s\.ply: it is a directory"):
        check_writable(tmp_path / "s.ply")
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputWriteError, match="is a file, not a directory"):
        check_writable(tmp_path / "file" / "sub" / "s.ply")
    with pytest.raises(OutputWriteError, match="not a directory"):
        save_scene(blob_scene(10), tmp_path / "file" / "s.ply")
    check_writable(tmp_path / "new" / "folder" / "s.ply")
    assert not (tmp_path / "new").exists()  # the check creates nothing


def test_an_output_group_appears_together_or_not_at_all(tmp_path, monkeypatch):
    out = tmp_path / "v.ply"
    with OutputGroup() as group:
        group.write(companion(out, ".json"), lambda tmp: atomic_write_text(tmp, "{}"))
        group.write(out, lambda tmp: save_scene(blob_scene(30), tmp, fmt="ply"))
    assert group.targets == [tmp_path / "v.json", out] and listing(tmp_path) == ["v.json", "v.ply"]
    old = {p: (tmp_path / p).read_bytes() for p in listing(tmp_path)}
    faults = Faults(monkeypatch, after_bytes=300)  # room for the JSON, not for the scene
    faults.arm(tmp_path, errno.ENOSPC)
    with pytest.raises(OutputWriteError, match=rf"cannot write {out}: no space"), OutputGroup() as group:
        group.write(companion(out, ".json"), lambda tmp: atomic_write_text(tmp, '{"new": 1}'))
        group.write(out, lambda tmp: save_scene(blob_scene(30), tmp, fmt="ply"))
    assert {p: (tmp_path / p).read_bytes() for p in listing(tmp_path)} == old  # --force's old files kept


# ====================================================================== convert and render: one line, exit 2
@pytest.mark.parametrize("code", list(CODES))
@pytest.mark.parametrize("command", ["convert", "render", "turntable"])
def test_commands_report_a_failing_disk_in_one_line(tmp_path, monkeypatch, capsys, command, code):
    src = tmp_path / "in.ply"
    save_scene(blob_scene(30, seed=2), src)
    out_dir = tmp_path / "full"
    out_dir.mkdir()
    out = out_dir / {"convert": "c.v1.5.spz", "render": "r.png", "turntable": "t.gif"}[command]
    argv = {"convert": ["convert", str(src), str(out)],
            "render": ["render", str(src), "--width", "32", "--out", str(out)],
            "turntable": ["render", str(src), "--turntable", "2", "--width", "32", "--out", str(out)]}[command]
    Faults(monkeypatch).arm(out_dir, code)
    assert run(argv) == 2
    err = capsys.readouterr().err.strip()
    line = err.splitlines()[-1]  # (a turntable's progress bar comes first)
    assert line.startswith(f"gstyle {argv[0]}: error: cannot write {out}") and CODES[code] in line, err
    assert "Traceback" not in err and err.count("error") == 1
    assert listing(out_dir) == []


def test_convert_to_a_directory_or_under_a_file_is_refused_before_reading(tmp_path, capsys):
    src = tmp_path / "in.ply"
    save_scene(blob_scene(20), src)
    (tmp_path / "d.ply").mkdir()
    assert run(["convert", str(src), str(tmp_path / "d.ply"), "--force"]) == 2
    assert capsys.readouterr().err.strip() == f"gstyle convert: error: cannot write {tmp_path / 'd.ply'}: it is a " \
                                              "directory"
    assert run(["convert", str(src), str(tmp_path / "in.ply" / "x.ply")]) == 2
    assert "is a file, not a directory" in capsys.readouterr().err


# ====================================================================== the studio
def test_studio_export_failure_is_one_line_and_leaves_no_take(tmp_path, monkeypatch):
    from app.events import Events
    from app.export import export_engine, summary_path
    from app.panels import PanelState
    from app.status_line import StatusLine
    from app.studio_sync import EngineSync
    from app.takes_view import TakesView
    from app.worker import WorkerState
    from gstyle_core.errors import one_line_error

    class Engine:
        def stylized_scene(self):
            return blob_scene(25, seed=4)

    folder = tmp_path / "studio out"
    path = folder / "take 0.5.compressed.ply"
    faults = Faults(monkeypatch)
    faults.arm(folder, errno.ENOSPC)
    with pytest.raises(OutputWriteError) as caught:
        export_engine(Engine(), path, None, {})
    line = one_line_error(caught.value)
    assert line.startswith(f"cannot write {folder}") and "no space left on the device" in line and "\n" not in line
    assert listing(folder) == []

    panel = PanelState()
    status = StatusLine(panel)
    empty = type("Empty", (), {"count": 0})()  # nothing shown: a take gets no thumbnail
    takes = TakesView(None, panel, status, folder, views=type("Views", (), {"stylized": empty})(), control=None,
                      view_key=lambda: "", input_path=lambda: None, open_path=lambda path: False)  # no engine: no view
    studio = EngineSync(panel, status, Events(), engine=None, stylized=empty, showing_result=lambda: False,
                        shelve=takes.shelve_exports)
    state = WorkerState()
    state.export_failures.append(f"export: {line}")
    studio._sync_exports(state)
    assert studio.panel.status == f"export: {line}" and takes.shelf.takes == []

    faults.disarm()
    assert export_engine(Engine(), path, None, {}) == str(path)
    assert summary_path(path) == folder / "take 0.5.json" and listing(folder) == ["take 0.5.compressed.ply",
                                                                                 "take 0.5.json"]
    faults.arm(folder, errno.EROFS)  # the export made it; takes.json cannot be saved
    state.exported.append(str(path))
    studio._sync_exports(state)
    takes.show_write_error()
    assert [t.path for t in takes.shelf.takes] == [str(path)]  # the take is on the shelf for this session
    assert studio.panel.status.startswith(f"exported {path} (kept as take 1); cannot write {folder / 'takes.json'}"
                                          ": read-only file system"), studio.panel.status
    assert load_scene(path)[0].count == 25
