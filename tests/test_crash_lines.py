"""No traceback ever reaches the artist (issue #48): an unexpected error in a ``gstyle`` command is one line on stderr
(what failed, where: for ``stylize`` the phase, the step and the controls in force, with the ``--resume`` command
that goes on from the last finished step), exit status 1, and its traceback in a crash log in the cache folder.

The stylization is the bundled demo at 64 px with one finer level at 80 px (fp32, ``tests/conftest.py``). A failure
is injected into each phase in turn (its class's ``step`` raises at its Nth call); each run resumes the checkpoint
the failure before it kept, so the chain passes every phase once and ends with the outputs written.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from gstyle_core.cli import run
from gstyle_core.engine import phases
from gstyle_core.engine.checkpoint import read_checkpoint, stylize_checkpoint_path

LOG = re.compile(r"; traceback in (\S+\.log)$")


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """A private cache folder: the crash logs, checkpoints and kept runs of these runs go there."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("GSTYLE_CACHE", str(folder))
    return folder


def inject(monkeypatch, cls: type, nth: int, final: bool | None = None) -> None:
    """``cls.step`` raises a two-line ``RuntimeError`` at its ``nth`` call (``final``: only the colour matches
    whose ``final`` is that count; the others run)."""
    original, calls = cls.step, [0]

    def step(self):
        if final is None or self.final == final:
            calls[0] += 1
            if calls[0] == nth:
                raise RuntimeError(f"injected into {cls.__name__}\nsecond line of the message")
        return original(self)

    monkeypatch.setattr(cls, "step", step)


def failure_line(capsys) -> tuple[str, str]:
    """The run's one line of failure (the last line on stderr, after the progress bar's) and everything it
    printed."""
    captured = capsys.readouterr()
    lines = [line for line in re.split(r"[\r\n]", captured.err) if line.strip()]
    told = [line for line in lines if line.startswith("gstyle ")]
    assert len(told) == 1 and told[0] == lines[-1], lines[-3:]
    return told[0], captured.out + captured.err


def check_crash_log(line: str, *expected: str) -> str:
    """The crash log the line names: it exists and holds the traceback, the whole message and ``expected``."""
    found = LOG.search(line)
    assert found, line
    log = Path(found.group(1)).read_text()
    assert "Traceback (most recent call last)" in log and "second line of the message" in log
    for text in expected:
        assert text in log, text
    return log


# phase class, its Nth step fails, only the final colour match, the phase the engine names (the stylization's 5th
# step is still a stylization step; refit steps come after its first split)
CHAIN = [
    (phases.GroundTruth, 3, None, "ground_truth"),
    (phases.Preprocess, 5, None, "preprocess"),
    (phases.ColourMatch, 1, False, "colour_match"),
    (phases.Stylize, 5, None, "stylize"),
    (phases.Refine, 3, None, "refine"),
    (phases.ColourMatch, 1, True, "finish"),
]
CONTROLS = "controls: strength=2 (the others the preview preset's)"


@pytest.mark.slow
def test_a_failure_in_each_phase_is_one_line_and_the_run_resumes_to_the_end(cache, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out" / "demo.ply"
    args = ["stylize", "--working-width", "64", "--refine-widths", "80", "--display-width", "0", "--strength", "2",
            "--out", str(out)]
    resume = f"gstyle {shlex.join([*args, '--resume'])} goes on from there"
    kept_step = None
    for cls, nth, final, phase in CHAIN:
        with monkeypatch.context() as patch:
            inject(patch, cls, nth, final)
            code = run(args + (["--resume"] if kept_step is not None else []))
        line, printed = failure_line(capsys)
        assert code == 1, line
        assert "Traceback" not in printed
        if kept_step is not None:  # it went on from the checkpoint the failure before kept
            assert f"skipped {kept_step} of" in printed
        head = re.match(rf"gstyle stylize: unexpected error in phase {phase} at step (\d+) of \d+: RuntimeError: "
                        rf"injected into {cls.__name__}; {re.escape(CONTROLS)}; the run up to step (\d+) is kept: ",
                        line)
        assert head and int(head.group(1)) == int(head.group(2)) + 1, line
        assert resume in line and "second line" not in line
        check_crash_log(line, f"in phase {phase} at step {head.group(1)}", "all controls: lambda_clip=0", "--out")
        state, meta = read_checkpoint(stylize_checkpoint_path(out))
        kept_step = int(head.group(2))
        assert meta["step"] == state["global_step"] == kept_step and meta["phase"] == phase
        assert not out.exists()  # nothing half-written beside --out

    finished_after_the_run(args, kept_step, monkeypatch, capsys)
    assert run([*args, "--resume"]) == 0
    printed = capsys.readouterr()
    assert "skipped" in printed.out and "Traceback" not in printed.err
    assert out.exists() and out.with_suffix(".json").exists()


def finished_after_the_run(args: list[str], kept_step: int, monkeypatch, capsys) -> None:
    """The last step resumed and done, measuring the run fails: the finished run is kept for --resume."""
    import gstyle_core.cli.stylize as stylize_cli

    def broken(*_a, **_k):
        raise ZeroDivisionError("injected after the run\nsecond line of the message")

    with monkeypatch.context() as patch:
        patch.setattr(stylize_cli, "evaluate_run", broken)
        assert run([*args, "--resume"]) == 1
    line, printed = failure_line(capsys)
    assert f"skipped {kept_step} of" in printed and "Traceback" not in printed
    assert re.match(rf"gstyle stylize: unexpected error after the last step \((\d+) of \1\): ZeroDivisionError: "
                    rf"injected after the run; {re.escape(CONTROLS)}; the run up to step \1 is kept: ", line), line
    check_crash_log(line, "in broken")


def test_the_controls_named_are_those_that_differ_from_the_preset(cache):
    """The demo's calibrated preview: its own values are the preset's, a finer level's weights too (a calibrated
    360° run with levels has its own), a control moved is named."""
    from gstyle_core.engine.build import BuildRequest, build_stylizer
    from gstyle_core.engine.run_crash import controls_in_force, where_the_run_is

    engine = build_stylizer(BuildRequest(overrides={"working_width": 32})).engine
    assert controls_in_force(engine) == "controls: the preview preset's"
    engine.refine()
    assert controls_in_force(engine) == "controls: the preview preset's"
    engine.set_params(lambda_tv=0.5, keep_colours=1)
    assert controls_in_force(engine) == "controls: lambda_tv=0.5, keep_colours=1 (the others the preview preset's)"
    engine.step()
    assert where_the_run_is(engine) == f"in phase ground_truth at step 2 of {engine.total_steps()}"


def test_other_commands_name_themselves_and_their_log(cache, tmp_path, monkeypatch, capsys):
    import gstyle_core.io as io

    def broken(*_a, **_k):
        raise TypeError("injected into load_scene\nsecond line of the message")

    monkeypatch.setattr(io, "load_scene", broken)
    assert run(["info", "scene.ply"]) == 1
    line, printed = failure_line(capsys)
    assert re.match(r"gstyle info: unexpected error: TypeError: injected into load_scene; traceback in \S+\.log$", line)
    log = check_crash_log(line, "command: gstyle info scene.ply")
    assert Path(LOG.search(line).group(1)).parent == cache / "crashes"
    assert "Traceback" not in printed and "Traceback" in log


def test_a_cache_that_refuses_files_still_gives_one_line(tmp_path, monkeypatch, capsys):
    import gstyle_core.io as io

    blocked = tmp_path / "a file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("GSTYLE_CACHE", str(blocked))

    def broken(*_a, **_k):
        raise ValueError("injected")

    monkeypatch.setattr(io, "load_scene", broken)
    assert run(["info", "scene.ply"]) == 1
    line, _printed = failure_line(capsys)
    assert line.startswith("gstyle info: unexpected error: ValueError: injected; the traceback could not be saved (")


def test_a_run_that_cannot_be_kept_says_so_on_its_line(cache, tmp_path, monkeypatch, capsys):
    """A full cache folder: the failure's line says the run could not be kept, and gives no --resume."""
    import errno

    from gstyle_core.engine import checkpoint
    from gstyle_core.errors import OutputWriteError

    def full(path, *_a, **_k):
        raise OutputWriteError(path, "no space left on the device", errno.ENOSPC)

    monkeypatch.setattr(checkpoint, "save_checkpoint", full)
    inject(monkeypatch, phases.GroundTruth, 2)
    out = tmp_path / "full.ply"
    assert run(["stylize", "--working-width", "32", "--display-width", "0", "--out", str(out)]) == 1
    line, printed = failure_line(capsys)
    assert "Traceback" not in printed and "--resume" not in line and not out.exists()
    assert re.match(r"gstyle stylize: unexpected error in phase ground_truth at step 2 of \d+: RuntimeError: "
                    r"injected into GroundTruth; controls: the preview preset's; the run could not be kept \(cannot "
                    r"write \S+\.ckpt: no space left on the device\); traceback in \S+\.log$", line), line


def test_a_bug_in_the_studio_is_one_line_and_a_crash_log(cache, capsys, monkeypatch):
    import app.main as studio_main

    def broken(args):
        raise RuntimeError("injected into the studio\nsecond line of the message")

    monkeypatch.setattr(studio_main, "run", broken)
    assert studio_main.main(["--headless", "--frames", "1"]) == 1
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in captured.out + captured.err
    assert lines[0].startswith("gstyle-studio: unexpected error: RuntimeError: injected into the studio;")
    check_crash_log(lines[0], "second line of the message")
