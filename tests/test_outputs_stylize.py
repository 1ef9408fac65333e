"""``gstyle stylize``'s outputs (issue #25): OUT.ply with OUT.json, OUT_before.png and OUT_after.png named by the one
rule (``outputs.companion``), refused like OUT.ply without ``--force``; a write that fails after the run (a full
disk, a forbidden or read-only folder) is one line that says where the run is kept and the exact command that
finishes it, and that command does.

The engine is a stand-in of nine steps in three phases (no rendering, no networks): each run takes a fraction of a
second, so the CLI's whole path (checks, checkpoints, outputs, resume) is exercised many times.
"""

from __future__ import annotations

import errno
import shlex
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from faults import Faults, listing
from synthetic import blob_scene

from gstyle_core.cli import run
from gstyle_core.cli import stylize as cli
from gstyle_core.engine.build import BuiltEngine
from gstyle_core.engine.checkpoint import stylize_checkpoint_path
from gstyle_core.engine.kept_runs import find_result_state
from gstyle_core.io import load_scene

PHASES = ("ground_truth", "stylize", "finish")
STEPS_PER_PHASE = 3
TOTAL = STEPS_PER_PHASE * len(PHASES)


class TinySettings:
    scene_kind, preset, working_width, style_weights = "forward", "preview", 32, [1.0]

    def to_dict(self) -> dict:
        return {"preset": self.preset, "working_width": self.working_width}


class TinyEngine:
    """Nine steps in three phases; its state is the step count; the stylized scene's colour follows it."""

    def __init__(self) -> None:
        self.input_scene = blob_scene(40, seed=7)
        self.settings, self.cameras, self.full_cameras = TinySettings(), [0, 1, 2], None
        self.clip_name, self.decisions, self.timings = "CLIP", {"clip": "off (test engine)"}, {}
        self.global_step = 0

    @property
    def phase(self) -> str:
        return PHASES[self.global_step // STEPS_PER_PHASE] if self.global_step < TOTAL else "done"

    @property
    def done(self) -> bool:
        return self.global_step >= TOTAL

    def total_steps(self) -> int:
        return TOTAL

    def step(self):
        phase = self.phase
        self.global_step += 1
        return SimpleNamespace(phase=phase, total_steps=TOTAL, losses={"nnfm": 1.0 / self.global_step}, message="")

    def state_dict(self) -> dict:
        return {"phase": self.phase, "global_step": self.global_step}

    def load_state_dict(self, state: dict) -> None:
        self.global_step = int(state["global_step"])

    def stylized_scene(self):
        scene = blob_scene(40, seed=7)
        scene.sh_dc[:] = self.global_step / TOTAL
        return scene


@pytest.fixture
def tiny(monkeypatch, tmp_path):
    """The stand-in engine behind ``gstyle stylize``; a private cache folder; ``built`` counts engine builds."""
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    built = []

    def build(request):
        built.append(request)
        return BuiltEngine(TinyEngine(), blob_scene(40, seed=7), None, SimpleNamespace(source="test"),
                           np.zeros((8, 8, 3), np.float32))

    monkeypatch.setattr(cli, "build_stylizer", build)
    monkeypatch.setattr(cli, "evaluate_run", lambda engine, scene, style, **_: {
        "images": (np.zeros((6, 8, 3), np.float32), np.ones((6, 8, 3), np.float32)),
        "initial": {"nnfm": 2.0}, "final": {"nnfm": 1.0}, "nnfm_drop": 0.5, "structure": 0.9})
    return built


def stylize(out: Path, *extra: str) -> list[str]:
    return ["stylize", "--out", str(out), "--checkpoint-every", "0", *extra]


def files_of(out: Path) -> list[Path]:
    base = out.name[: -len(".compressed.ply")] if out.name.lower().endswith(".compressed.ply") else out.name[:-4]
    return [out, *(out.with_name(base + tail) for tail in (".json", "_before.png", "_after.png"))]


def fail_outputs_with(monkeypatch, faults: Faults, *roots_codes) -> None:
    """Arm the faults when the first run is over and its outputs are being written (a disk that filled up
    meanwhile); later runs write as they are (``faults.disarm()``: space freed)."""
    write, calls = cli._write_outputs, []

    def armed(*args, **kwargs):
        if not calls:
            for root, code in roots_codes:
                faults.arm(root, code)
        calls.append(1)
        return write(*args, **kwargs)

    monkeypatch.setattr(cli, "_write_outputs", armed)


# ====================================================================== names
@pytest.mark.parametrize("name", ["seal0.5.ply", "v1.0.ply", "my scene.ply", "étude №2 · 0.25.ply",
                                  "web.v2.compressed.ply", "UPPER.PLY", "a.b.c.d.ply"])
def test_every_file_is_named_from_the_whole_output_name(tiny, tmp_path, capsys, name):
    out = tmp_path / "out" / name
    assert run(stylize(out)) == 0
    files = files_of(out)
    assert listing(out.parent) == sorted(p.name for p in files)
    assert f"wrote {', '.join(map(str, files))} (" in capsys.readouterr().out  # the files actually written
    assert load_scene(out)[0].count == 40
    assert not stylize_checkpoint_path(out).exists()  # a complete run leaves no checkpoint
    kept = find_result_state(out)  # its run is kept for the studio's Continue
    assert kept is not None and kept[1]["config"]["preset"] == "preview" and kept[1]["config"]["scene"] is None


def test_dotted_names_never_share_a_summary_and_companions_need_force(tiny, tmp_path, capsys):
    v10, v15 = tmp_path / "v1.0.ply", tmp_path / "v1.5.ply"
    assert run(stylize(v10)) == 0 and run(stylize(v15)) == 0
    assert [p for p in listing(tmp_path) if not p.startswith("cache")] == sorted(
        p.name for p in files_of(v10) + files_of(v15))  # eight files: two runs, nothing shared
    capsys.readouterr()
    v10.unlink()  # the scene gone, its summary still there: refused, named
    assert run(stylize(v10)) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"gstyle stylize: error: {tmp_path / 'v1.0.json'}, {tmp_path / 'v1.0_before.png'}, " \
                  f"{tmp_path / 'v1.0_after.png'} exist; pass --force to overwrite them"
    (tmp_path / "v1.0.json").write_text("{}")
    assert run(stylize(v10, "--force")) == 0 and v10.is_file()
    assert '"gaussians_after": 40' in (tmp_path / "v1.0.json").read_text()  # the forced run's own summary
    assert '"gaussians_after": 40' in (tmp_path / "v1.5.json").read_text()  # the other run's, untouched


def test_an_input_is_never_a_companion(tiny, tmp_path, capsys):
    out = tmp_path / "x.ply"
    style = tmp_path / "x_before.png"
    style.write_bytes(b"painting")
    assert run(stylize(out, "--style", str(style), "--force")) == 2
    assert "refusing to overwrite the input file" in capsys.readouterr().err
    assert style.read_bytes() == b"painting" and tiny == []


# ====================================================================== failures after the run
@pytest.mark.parametrize("code, cause, remedy", [
    (errno.ENOSPC, "no space left on the device", "free some space"),
    (errno.EACCES, "permission denied", "make the output folder writable"),
    (errno.EROFS, "read-only file system", "make the output folder writable")])
def test_a_failed_write_keeps_the_run_and_its_resume_command_finishes_it(tiny, tmp_path, monkeypatch, capsys,
                                                                          code, cause, remedy):
    out_dir = tmp_path / "out dir"
    out = out_dir / "seal0.5.ply"
    faults = Faults(monkeypatch)
    fail_outputs_with(monkeypatch, faults, (out_dir, code))
    assert run(stylize(out, "--style", str(tmp_path / "no such.jpg"))) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    ckpt = stylize_checkpoint_path(out)
    command = "gstyle " + shlex.join(stylize(out, "--style", str(tmp_path / "no such.jpg"), "--resume"))
    assert err == (f"gstyle stylize: error: cannot write {out_dir / 'seal0.5.json'}: {cause}; the finished run is "
                   f"kept in {ckpt}: {remedy}, then run {command}")
    assert listing(out_dir) == [] and ckpt.is_file()  # nothing half-written, not even a companion

    faults.disarm()
    assert run(shlex.split(command)[1:]) == 0  # the exact command printed
    printed = capsys.readouterr().out
    assert f"resumed from {ckpt}: skipped {TOTAL} of {TOTAL} steps" in printed  # only the writes were left
    assert listing(out_dir) == sorted(p.name for p in files_of(out)) and not ckpt.exists()
    assert np.allclose(load_scene(out)[0].sh_dc, 1.0, atol=0.01)  # the finished run's colours


def test_a_full_cache_too_keeps_the_last_checkpoint(tiny, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out" / "s.ply"
    faults = Faults(monkeypatch)
    fail_outputs_with(monkeypatch, faults, (out.parent, errno.ENOSPC), (tmp_path / "cache", errno.ENOSPC))
    assert run(stylize(out)) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    ckpt = stylize_checkpoint_path(out)
    assert f"cannot write {out.parent / 's.json'}: no space left on the device; the run is kept up to its last " \
           f"checkpoint, {ckpt}: free some space, then run gstyle stylize --out {out} " in err
    faults.disarm()
    assert run(stylize(out, "--resume")) == 0
    assert f"skipped {2 * STEPS_PER_PHASE} of {TOTAL} steps" in capsys.readouterr().out  # the last phase end
    assert load_scene(out)[0].count == 40


def test_nothing_kept_is_said_too(tiny, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out" / "s.ply"
    faults = Faults(monkeypatch)
    faults.arm(tmp_path / "cache", errno.EROFS)  # no checkpoint at all, ever
    fail_outputs_with(monkeypatch, faults, (out.parent, errno.ENOSPC))
    assert run(stylize(out)) == 2
    captured = capsys.readouterr()
    assert captured.out.count("note: cannot write") == 1  # a failing checkpoint is said once; the run goes on
    last = captured.err.strip().splitlines()[-1]
    assert last.startswith(f"gstyle stylize: error: cannot write {out.parent / 's.json'}: no space left on the "
                           "device; the run could not be kept (cannot write ") and "read-only" in last


def test_failing_checkpoints_do_not_stop_the_run(tiny, tmp_path, monkeypatch, capsys):
    out = tmp_path / "s.ply"
    Faults(monkeypatch).arm(tmp_path / "cache", errno.ENOSPC)
    assert run(stylize(out)) == 0
    printed = capsys.readouterr().out
    note = f"note: cannot write {stylize_checkpoint_path(out)}: no space left on the device; the run goes on"
    assert printed.count(note) == 1
    assert listing(tmp_path / "cache" / "checkpoints") == []  # no half-written checkpoint either
    assert load_scene(out)[0].count == 40


def test_force_keeps_the_old_outputs_when_the_new_ones_cannot_be_written(tiny, tmp_path, monkeypatch, capsys):
    out = tmp_path / "s.ply"
    assert run(stylize(out)) == 0
    old = {p.name: p.read_bytes() for p in files_of(out)}
    fail_outputs_with(monkeypatch, Faults(monkeypatch, after_bytes=2000), (tmp_path, errno.ENOSPC))
    assert run(stylize(out, "--force")) == 2
    assert {p.name: p.read_bytes() for p in files_of(out)} == old
    assert [p for p in listing(tmp_path) if p.startswith(".")] == []  # no temporary left


# ====================================================================== failures before the run
@pytest.mark.parametrize("code, cause", [(errno.EACCES, "permission denied"), (errno.EROFS, "read-only file system")])
def test_a_folder_that_refuses_files_is_found_before_the_run(tiny, tmp_path, monkeypatch, capsys, code, cause):
    out = tmp_path / "ro" / "new" / "s.ply"
    (tmp_path / "ro").mkdir()
    Faults(monkeypatch).arm(tmp_path / "ro", code)
    assert run(stylize(out)) == 2
    assert capsys.readouterr().err.strip() == f"gstyle stylize: error: cannot write {out}: {cause}"
    assert tiny == [] and listing(tmp_path / "ro") == []  # nothing loaded, nothing created


def test_an_output_that_is_a_directory_is_found_before_the_run(tiny, tmp_path, capsys):
    (tmp_path / "s.ply").mkdir()
    assert run(stylize(tmp_path / "s.ply", "--force")) == 2
    assert capsys.readouterr().err.strip() == f"gstyle stylize: error: cannot write {tmp_path / 's.ply'}: it is a " \
                                              "directory"
    assert tiny == []


def test_a_stop_whose_checkpoint_cannot_be_written_says_so(tiny, tmp_path, monkeypatch, capsys):
    import contextlib

    from gstyle_core.engine import checkpoint

    monkeypatch.setattr(checkpoint, "deferred_interrupts", lambda: contextlib.nullcontext({"stop": True}))
    Faults(monkeypatch).arm(tmp_path / "cache", errno.EROFS)
    out = tmp_path / "s.ply"
    assert run(stylize(out)) == 130  # Ctrl+C after the first step
    printed = capsys.readouterr().out
    assert f"stopped after step 1; cannot write {stylize_checkpoint_path(out)}: read-only file system; no checkpoint " \
           "is kept" in printed
    assert listing(tmp_path / "cache") == [] and not out.exists()


def test_fit_names_its_summary_by_the_same_rule(tmp_path, monkeypatch):
    from gstyle_core.cli import fit as fit_cli

    args = SimpleNamespace(out=str(tmp_path / "fern.v1.5.compressed.ply"))
    fit_cli._write_outputs(args, blob_scene(30), {"gaussians": 30})
    assert listing(tmp_path) == ["fern.v1.5.compressed.ply", "fern.v1.5.json"]
    assert load_scene(tmp_path / "fern.v1.5.compressed.ply")[1].format == "ply-playcanvas-compressed"
    Faults(monkeypatch).arm(tmp_path / "full", errno.ENOSPC)
    with pytest.raises(OSError, match=r"cannot write .*fern\.ply: no space left on the device"):
        fit_cli._write_outputs(SimpleNamespace(out=str(tmp_path / "full" / "fern.ply")), blob_scene(30), {})
    assert listing(tmp_path / "full") == []  # the summary, written first, went with it
