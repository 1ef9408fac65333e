"""Undo and redo of the artist's parameter changes (issue #35 item 1, first part): every ``set_params`` the panel
issues (sliders, term on/off, switches such as keep colours, the style mix, Reset all) is one step back with Ctrl+Z
and forward again with Ctrl+Shift+Z or Ctrl+Y. A slider dragged over many frames is one step: changes of the same
controls less than ``COALESCE_SECONDS`` apart join the step before. No GL, no engine: the studio applies the values
an undo or redo returns as it applies the panel's (the engine returns the colours of a finished run bit for bit when
a switch goes back, ``Stylizer._switch_chroma``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

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


class EditHistory:
    """The undo and redo stacks of parameter edits."""

    def __init__(self, limit: int = LIMIT) -> None:
        self.limit = limit
        self.done: list[ParamEdit] = []
        self.undone: list[ParamEdit] = []

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
        if last is not None and last.after.keys() == after.keys() and now - last.at < COALESCE_SECONDS:
            last.after, last.at = after, now  # the same drag: one step from where it started
            return
        self.done.append(ParamEdit(before, after, now))
        del self.done[:-self.limit]

    def undo(self) -> ParamEdit | None:
        """The step to take back (apply its ``before``), or None."""
        if not self.done:
            return None
        edit = self.done.pop()
        self.undone.append(edit)
        if self.done:
            self.done[-1].at = float("-inf")  # the next change is a step of its own
        return edit

    def redo(self) -> ParamEdit | None:
        """The step to take again (apply its ``after``), or None."""
        if not self.undone:
            return None
        edit = self.undone.pop()
        edit.at = float("-inf")  # a redone step never swallows the next change
        self.done.append(edit)
        return edit
