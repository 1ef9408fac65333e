"""Where a run was when an unexpected error stopped it, in words for its one line (``gstyle_core/crash.py``): the
phase and step, and the controls in force. ``gstyle stylize`` and the studio's worker word their failures with it.
Engines without these attributes (test doubles) give what they have."""

from __future__ import annotations

from typing import Any


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
