"""When a running engine saves its state on its own (the studio's worker): often enough that a killed process loses
at most about ``interval`` seconds of steps, and never so often that saving takes more than ``share`` of the time."""

from __future__ import annotations

import time
from collections.abc import Callable

AUTOSAVE_SECONDS = 30.0  # a worker killed mid-run loses at most this much stepping (plus one save's time)
AUTOSAVE_SHARE = 0.03  # the most of the stepping time that saving may take (issue #65: a crash costs at most a minute)


class SavePacing:
    """The next save's time: ``interval`` seconds after the last one ended, or longer when that save took more than
    ``share`` of the interval (a 3 s save at 3 %: 100 s). The clock starts when stepping starts (``start``)."""

    def __init__(self, interval: float = AUTOSAVE_SECONDS, share: float = AUTOSAVE_SHARE,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if interval <= 0 or not 0 < share <= 1:
            raise ValueError(f"save pacing needs interval > 0 and 0 < share <= 1, got {interval}, {share}")
        self.interval, self.share, self.clock = float(interval), float(share), clock
        self.next_at: float | None = None
        self.last_cost = 0.0

    def start(self) -> None:
        """Stepping (re)starts: the first save is ``interval`` seconds from now."""
        self.next_at = self.clock() + self.interval

    def due(self) -> bool:
        """True when a save is owed (never before ``start``)."""
        return self.next_at is not None and self.clock() >= self.next_at

    def saved(self, seconds: float) -> None:
        """A save that took ``seconds`` just ended: the next one is an interval away, further for a costly save."""
        self.last_cost = max(0.0, float(seconds))
        self.next_at = self.clock() + max(self.interval, self.last_cost / self.share)
