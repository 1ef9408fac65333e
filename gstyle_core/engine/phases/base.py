"""The interface every phase of a run has, and what one step reports.

A phase is built from the run state alone (``Phase(run)``), fresh or to be resumed: a resumed phase is built by
the same constructor, then ``load_state_dict`` puts back what ``state_dict`` saved. ``start()`` is called once,
when the run reaches the phase (never after ``load_state_dict`` of a started phase); then ``step()`` until
``finished``. ``remaining_steps()`` is what the run's progress total adds up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..run_state import RunState


@dataclass
class StepReport:
    """What one step did."""

    phase: str
    step: int
    total_steps: int
    losses: dict[str, float] = field(default_factory=dict)
    seconds: float = 0.0
    gaussians: int = 0
    colours_changed: bool = False
    geometry_changed: bool = False
    done: bool = False
    message: str = ""
    width: int = 0  # the width (px) the step worked at: the working width, or a finer level's


class Phase:
    """Base class: one stage of a run over the shared ``RunState``."""

    name = "phase"  # the phase's key in checkpoints and its name in reports

    def __init__(self, run: RunState) -> None:
        self.run = run
        self.started = False

    @property
    def current(self) -> str:
        """The name reports and ``engine.phase`` give while this phase runs (a stage within it may have its own)."""
        return self.name

    def start(self) -> None:
        """Called once when the run reaches this phase (decisions that need the earlier phases' results)."""
        self.started = True

    @property
    def finished(self) -> bool:
        """True once the phase has nothing left to do."""
        raise NotImplementedError

    def remaining_steps(self) -> int:
        """Steps still to come in this phase, as planned now."""
        raise NotImplementedError

    def step(self) -> StepReport:
        """One unit of work; the runner fills in the step counts, timing and Gaussian count."""
        raise NotImplementedError

    def report(self, **kw: Any) -> StepReport:
        """A ``StepReport`` of this phase (``current`` as its name)."""
        return StepReport(self.current, 0, 0, **kw)

    def state_dict(self) -> dict[str, Any]:
        """What a resumed phase needs (the shared tensors are the run state's)."""
        return {"started": self.started}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore ``state_dict()``."""
        self.started = bool(state["started"])
