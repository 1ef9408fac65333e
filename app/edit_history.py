"""Undo and redo in the studio (issue #35 item 1): every ``set_params`` the panel issues (sliders, term on/off,
switches such as keep colours, the style mix, Reset all) is one step back with Ctrl+Z and forward again with
Ctrl+Shift+Z or Ctrl+Y. A slider dragged over many frames is one step: changes of the same controls less than
``COALESCE_SECONDS`` apart join the step before. The region tool's selection is undone the same way
(``RegionEdit``: turned on or off, the box placed, dragged or resized, a rectangle selected). A stylized result that
a restart, a refine or another scene or painting replaces is a step too (``ResultEdit``): the engine wrote it to disk
first (scene and summary), and undo opens it as a result. A painting opened, mixed in or removed, or another
quality, when no result was replaced is a step of its own (``ChoiceEdit``): undo puts the choice before it back (the
engine restarts with it; a result made after the change is saved first and comes back on redo). No GL, no engine
here: the studio carries the steps out (the engine returns the colours of a finished run bit for bit when a switch
goes back, ``LiveControls.switch_chroma``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

COALESCE_SECONDS = 0.75
LIMIT = 500


@dataclass
class ParamEdit:
    """One step: the controls' values before and after it, and when it was last extended."""

    before: dict[str, float]
    after: dict[str, float]
    at: float

    def describe(self) -> str:
        """``lambda_nnfm 100 -> 200`` (several controls: their names)."""
        if len(self.after) == 1:
            (name, value), = self.after.items()
            return f"{name} {self.before.get(name, value):g} -> {value:g}"
        return ", ".join(sorted(self.after))

    def brings_back(self, name: str) -> str:
        """What undo (``name`` "undo") or redo puts back: ``lambda_nnfm back to 100`` / ``lambda_nnfm to 200``."""
        values = self.before if name == "undo" else self.after
        if len(self.after) == 1:
            (key, value), = self.after.items()
            return f"{key} {'back ' if name == 'undo' else ''}to {values.get(key, value):g}"
        return f"{', '.join(sorted(self.after))} as they were {'before' if name == 'undo' else 'set'}"


@dataclass
class ResultEdit:
    """A stylized result replaced by ``action`` ("restart", "refine", "open"): ``before`` the file it was saved to;
    ``after`` the file the result that replaced it is saved to when an undo leaves it (None until then)."""

    before: Path
    action: str
    after: Path | None = None
    at: float = float("-inf")

    def describe(self) -> str:
        return f"the result before {self.action} ({self.before.name})"

    def brings_back(self, name: str) -> str:
        """What undo (``name`` "undo": the result before) or redo (the one after, once an undo saved it) opens."""
        if name == "undo":
            return self.describe()
        return f"the result after {self.action} ({self.after.name if self.after else 'not saved: nothing to open'})"


@dataclass
class ChoiceEdit:
    """A choice that restarts the engine, made when no result was replaced: ``kind`` "painting" (``before`` and
    ``after`` are ``(painting, second painting or "", mix)``) or "quality" (the preset's name); ``result_after`` the
    file the result made after the choice was saved to when an undo left it (redo opens it), None until then."""

    kind: str
    before: Any
    after: Any
    result_after: Path | None = None
    at: float = float("-inf")

    def describe(self) -> str:
        if self.kind == "quality":
            return f"the quality ({self.before} -> {self.after})"

        def names(state: tuple[str, str, float]) -> str:
            return " + ".join(Path(p).name for p in state[:2] if p) or "no painting"

        return f"the painting ({names(self.before)} -> {names(self.after)})"

    def brings_back(self, name: str) -> str:
        """What undo (``name`` "undo": the choice before) or redo (the choice again, or the result made with it) puts
        back."""
        if name == "redo" and self.result_after is not None:
            return f"the result made after it ({self.result_after.name})"
        state = self.before if name == "undo" else self.after
        if self.kind == "quality":
            return f"the {state} quality"
        return f"the painting {' + '.join(Path(p).name for p in state[:2] if p) or '(none)'}"


def _same_region(a: tuple, b: tuple) -> bool:
    """Two region states (on, box, rectangle mask) select the same."""
    if a[0] != b[0] or a[1] != b[1]:
        return False
    if a[2] is None or b[2] is None:
        return a[2] is b[2]
    return a[2] is b[2] or bool(np.array_equal(a[2], b[2]))


@dataclass
class RegionEdit:
    """The region tool's selection before and after a change (``(on, box, rectangle mask)``: the tool turned on or
    off, its box placed, moved or resized, a rectangle selected); a drag is one step."""

    before: tuple
    after: tuple
    at: float

    def describe(self) -> str:
        return "the region selection"

    def brings_back(self, name: str) -> str:
        """The selection before the change (``name`` "undo") or after it."""
        return f"the region selection {'before' if name == 'undo' else 'after'} the change"


Edit = ParamEdit | ResultEdit | RegionEdit | ChoiceEdit


class EditHistory:
    """The undo and redo stacks of parameter edits."""

    def __init__(self, limit: int = LIMIT) -> None:
        self.limit = limit
        self.done: list[Edit] = []
        self.undone: list[Edit] = []

    def record(self, before: dict[str, float], after: dict[str, float], now: float | None = None) -> None:
        """A change the artist made: ``before`` the values of the controls in ``after`` until now. A change that
        changes nothing is not a step; a new change forgets what was undone."""
        now = time.monotonic() if now is None else now
        after = {k: float(v) for k, v in after.items()}
        before = {k: float(before[k]) for k in after if before.get(k) is not None}
        if all(before.get(k) == v for k, v in after.items()):
            return
        self.undone.clear()
        last = self.done[-1] if self.done else None
        if isinstance(last, ParamEdit) and last.after.keys() == after.keys() and now - last.at < COALESCE_SECONDS:
            last.after, last.at = after, now  # the same drag: one step from where it started
            return
        self.done.append(ParamEdit(before, after, now))
        del self.done[:-self.limit]

    def record_region(self, before: tuple, after: tuple, now: float | None = None) -> None:
        """A change of the region selection (``(on, box, rectangle mask)`` before and after); changes less than
        ``COALESCE_SECONDS`` apart (a box dragged or resized) join the step before; no change is no step."""
        now = time.monotonic() if now is None else now
        if _same_region(before, after):
            return
        self.undone.clear()
        last = self.done[-1] if self.done else None
        if isinstance(last, RegionEdit) and now - last.at < COALESCE_SECONDS:
            last.after, last.at = after, now
            return
        self.done.append(RegionEdit(before, after, now))
        del self.done[:-self.limit]

    def record_result(self, edit: ResultEdit | ChoiceEdit) -> None:
        """A result replaced (saved at ``edit.before``) or a choice made; a new step forgets what was undone."""
        self.undone.clear()
        self.done.append(edit)
        del self.done[:-self.limit]

    def last(self) -> Edit | None:
        """The newest step (None: none)."""
        return self.done[-1] if self.done else None

    def undo(self) -> Edit | None:
        """The step to take back (apply its ``before``), or None."""
        if not self.done:
            return None
        edit = self.done.pop()
        self.undone.append(edit)
        if self.done:
            self.done[-1].at = float("-inf")  # the next change is a step of its own
        return edit

    def redo(self) -> Edit | None:
        """The step to take again (apply its ``after``), or None."""
        if not self.undone:
            return None
        edit = self.undone.pop()
        edit.at = float("-inf")  # a redone step never swallows the next change
        self.done.append(edit)
        return edit
