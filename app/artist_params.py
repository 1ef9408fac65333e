"""The controls the artist set that the engine worker has not taken yet (issue #65 item 3): until it has, a slider
shows the artist's value, not the worker's echo of an older one; and the view owes the artist the first snapshot
taken after the change (``EngineSync`` uploads its geometry at once instead of at the streaming's pace).

Each ``set_params`` command sent to a worker is numbered (``sending``); the worker says how many it has taken
(its "params_taken" message, after the "params" echo of the last one: ``took``). A control set by command n shows
the worker's value again once the worker has taken n (that value or a newer one)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field


@dataclass
class ArtistParams:
    """One worker's numbering of the artist's control changes (a new worker, a new ``WorkerState``, starts at 0)."""

    sent: int = 0  # set_params commands sent to this worker
    taken: int = 0  # of them, those the worker has taken (its "params_taken")
    taken_at: int = 0  # the snapshots received when it said so (those after show the change)
    shown: int = 0  # the changes taken that the view has shown (``view_shown``)
    waiting: dict[str, int] = field(default_factory=dict)  # per control, the command that set it last

    def sending(self, keys: Iterable[str]) -> None:
        """A set_params command of ``keys`` goes to the worker."""
        self.sent += 1
        for key in keys:
            self.waiting[key] = self.sent

    def took(self, taken: int, snapshots_received: int) -> None:
        """The worker has taken ``taken`` commands (the snapshots after ``snapshots_received`` show them)."""
        self.taken, self.taken_at = taken, snapshots_received
        self.waiting = {k: n for k, n in self.waiting.items() if n > taken}

    def engine_values(self, params: dict[str, float]) -> dict[str, float]:
        """The worker's ``params`` the panel shows: all but the controls it has not taken the artist's value of."""
        return {k: v for k, v in params.items() if k not in self.waiting}

    def view_owed(self, snapshots_received: int) -> bool:
        """Whether a change the worker took is not shown yet and a snapshot taken after it has arrived."""
        return self.taken > self.shown and snapshots_received > self.taken_at

    def view_shown(self) -> None:
        """The view shows every change the worker has taken."""
        self.shown = self.taken
