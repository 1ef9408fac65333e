"""Where a run was when an unexpected error stopped it, in words for its one line (``gstyle_core/crash.py``): the
phase and step, and the controls in force. ``gstyle stylize`` and the studio's worker word their failures with it.
Engines without these attributes (test doubles) give what they have. Also ``gstyle stylize``'s lines for a run kept
after a failure (a bug, the GPU's failure, outputs that could not be written) with the command that goes on."""

from __future__ import annotations

import argparse
from typing import Any

from ..crash import RunCrashed, what_failed
from ..device import DeviceFailure
from ..errors import OutputWriteError, one_line_error


def where_the_run_is(engine: Any) -> str:
    """"in phase stylize at step 38 of 257" (the step that failed: one past the steps done); once every step is
    done, "after the last step (257 of 257)"; "" for an engine that cannot tell."""
    try:
        done, step, total = bool(engine.done), int(engine.global_step), int(engine.total_steps())
        phase = str(engine.phase)
    except Exception:  # noqa: BLE001 - an engine broken by the error, or a test double: no place to name
        return ""
    if done:
        return f"after the last step ({step} of {total})"
    return f"in phase {phase} at step {step + 1} of {total}"


def _preset_controls(engine: Any) -> dict[str, float]:
    """The controls' values the run's preset gives its scene and its levels (a calibrated 360° run with finer levels
    has weights of its own)."""
    from .settings import preset_values

    s = engine.settings
    return preset_values(s.preset, s.scene_kind, engine.camera_count, defaults=s.defaults,
                         clip_available=engine.clip_name == "CLIP", working_width=s.working_width,
                         refine_widths=s.refine_widths)


def controls_in_force(engine: Any) -> str:
    """"controls: strength=2, lambda_nnfm=50 (the others the preview preset's)": the live controls that differ
    from the preset's (``controls.read_controls``), or "controls: the preview preset's"; "" for an engine without
    settings."""
    from .controls import read_controls

    try:
        now, s = read_controls(engine.settings), engine.settings
    except Exception:  # noqa: BLE001 - a test double, or settings the error left unreadable
        return ""
    try:
        preset = _preset_controls(engine)
    except Exception:  # noqa: BLE001 - no preset to compare with: every control is named
        preset = {}
    differ = {k: v for k, v in now.items() if k not in preset or abs(preset[k] - v) > 1e-9 * max(1.0, abs(v))}
    if not differ:
        return f"controls: the {s.preset} preset's"
    named = ", ".join(f"{k}={v:g}" for k, v in differ.items())
    return f"controls: {named}" + (f" (the others the {s.preset} preset's)" if preset else "")


def all_controls(engine: Any) -> str:
    """Every control's value, ``name=value`` (the crash log's record); "" for an engine without settings."""
    from .controls import read_controls

    try:
        return "all controls: " + ", ".join(f"{k}={v:g}" for k, v in read_controls(engine.settings).items())
    except Exception:  # noqa: BLE001 - a test double
        return ""


def kept_for_the_cpu(exc: DeviceFailure, checkpointer, device: str) -> DeviceFailure:
    """The GPU failed in a run asked for on ``device``: the run as its last finished step left it is saved (a step
    that failed keeps none of its work) and the error, one line, says how to go on from there on the CPU."""
    if device == "cpu":
        return exc
    try:
        path = checkpointer.save()
    except Exception as error:  # noqa: BLE001 - a full disk, or a card that cannot give its tensors back: one line
        return type(exc)(f"{exc}; the run could not be kept ({one_line_error(error)})")
    return type(exc)(f"{exc}; the run so far is kept in {path}: the same command with --device cpu --resume goes "
                     "on from there")


def crashed_run(exc: Exception, engine, checkpointer, args: argparse.Namespace) -> RunCrashed:
    """``exc`` (a bug, not a bad input) with where the run was (its phase and step, or past its last step), the
    controls in force and, saved now, the run as its last finished step left it (a step that failed keeps none of
    its work) with the command that goes on from there; without a save, its last checkpoint if one was written."""
    step = getattr(engine, "global_step", None)
    try:
        path = checkpointer.save()
        kept = f"the run up to step {step} is kept: {resume_command(args)} goes on from there"
    except Exception as error:  # noqa: BLE001 - a full cache, or state the error left unsaveable: say so
        kept = f"the run could not be kept ({what_failed(error)})"
        path = checkpointer.path if checkpointer.path.exists() else None
        if path is not None:
            kept += f"; its last checkpoint is kept: {resume_command(args)} goes on from there"
    details = [all_controls(engine), f"checkpoint: {path or 'none'}"]
    return RunCrashed(exc, where_the_run_is(engine), controls_in_force(engine), kept, details)


def kept_run_error(exc: OutputWriteError, checkpointer, args: argparse.Namespace) -> OutputWriteError:
    """``exc`` (the outputs of a finished run could not be written) with, on the same line, where the run is kept
    and the exact command that writes them once the cause is fixed. The finished state is saved first, so that
    command only writes; if even that fails, the last checkpoint of the run (if any) is what is kept."""
    try:
        checkpointer.save()
        kept = f"the finished run is kept in {checkpointer.path}"
    except OutputWriteError as ckpt_exc:
        if not checkpointer.path.exists():
            return OutputWriteError(exc.filename, f"{exc.cause}; the run could not be kept ({ckpt_exc})", exc.errno)
        kept = f"the run is kept up to its last checkpoint, {checkpointer.path}"
    return OutputWriteError(exc.filename, f"{exc.cause}; {kept}: {_remedy(exc.errno)}, then run "
                                          f"{resume_command(args)}", exc.errno)


def _remedy(code: int | None) -> str:
    """What to do about a failed write, by its errno (the same --out is needed: the checkpoint is kept for it)."""
    import errno

    if code in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)):
        return "free some space"
    if code in (errno.EACCES, errno.EPERM, errno.EROFS):
        return "make the output folder writable"
    return "fix that"


def resume_command(args: argparse.Namespace) -> str:
    """The command that continues this run: the one given (``args.argv``, set by ``gstyle_core.cli.run``) with
    ``--resume``, quoted for a POSIX shell."""
    import shlex

    argv = getattr(args, "argv", None)
    if argv is None:
        return "the same command with --resume"
    argv = list(argv) + ([] if "--resume" in argv else ["--resume"])
    return "gstyle " + shlex.join(argv)
