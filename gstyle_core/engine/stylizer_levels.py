"""The finer levels of a run (``Stylizer``'s part): the widths it works at, the width under way, and ``refine()``, which
carries a run on at a finer width after its last level (a finished run included). A mixin of ``Stylizer``: it reads
the runner's ``settings``, ``phases``, ``run_state``, ``level_limit``, ``current_phase()``, ``set_params()`` and
``_settle()``.
"""

from __future__ import annotations

from .levels import check_refine_widths, level_widths, next_width
from .notes import note_levels
from .phases import ColourMatch, Refine
from .settings import level_weight_changes, ui_params


class LevelsMixin:
    """``Stylizer``'s levels: ``levels``, ``current_width``, ``next_level_width()`` and ``refine()``."""

    @property
    def levels(self) -> tuple[int, ...]:
        """Every width the run works at, coarse to fine: the working width, then its finer levels."""
        return level_widths(self.settings.working_width, self.settings.refine_widths)

    @property
    def current_width(self) -> int:
        """The width the run works at now: the level under way (or the last one, once done)."""
        current = self.current_phase()
        if isinstance(current, Refine):
            return current.width
        if current is None or isinstance(current, ColourMatch) and current.final:
            return self.levels[-1]
        return int(self.settings.working_width)

    def next_level_width(self) -> int | None:
        """The width ``refine()`` would add (twice the last, at most the photos' width), None where the run already
        ends at the largest a level may have or at the photos' width."""
        width = next_width(self.levels)
        if self.level_limit is not None:
            width = min(width, self.level_limit)
        return width if width > self.levels[-1] else None

    def refine(self, width: int | None = None) -> int:
        """Carry the run on at a finer level after its last one (default: twice the last width): a new ``Refine``
        phase goes before the final colour match, which runs again after it. Works at any point of a run, a finished
        one included; returns the level's width. ``ValueError`` for a width not finer than the last level's."""
        width = self.next_level_width() if width is None else int(width)
        if width is None:
            largest = "the photos' width" if self.level_limit is not None else "the largest a level may have"
            raise ValueError(f"the run already ends at {self.levels[-1]} px, {largest}")
        if self.level_limit is not None and width > self.level_limit:
            raise ValueError(f"a level of {width} px would fit photos enlarged: they are {self.level_limit} px wide")
        s = self.settings
        changes = level_weight_changes(s)  # a calibrated 360° preview's first level: the weights of runs with levels
        s.refine_widths = check_refine_widths((*s.refine_widths, width), s.working_width)
        if changes:
            before = ui_params(s)
            self.set_params(**changes)
            self.run_state.decisions["level_weights"] = (
                "the first finer level takes the calibrated weights of runs with finer levels: "
                + ", ".join(f"{k} {before[k]:g} -> {v:g}" for k, v in changes.items())
                + " (the content term does not hold edges as fine as these pixels; docs/notes/display-size.md)")
        level = Refine(self.run_state, width, len(s.refine_widths) - 1)
        finish = [p for p in self.phases if isinstance(p, ColourMatch) and p.final]
        self.phases = [p for p in self.phases if p not in finish] + [level] + finish
        for p in finish:
            p.reopen()
        note_levels(self.run_state.decisions, s)
        self._settle()
        return width
