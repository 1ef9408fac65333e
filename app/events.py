"""Notifications between the studio's parts (``app/studio.py``): a few typed events and a tiny synchronous bus.

A part that changes something others follow publishes an event; the parts that follow it subscribed when the
studio was built (in the order they were built, which is the order they hear it). Requests from one part to
another are method calls or callables handed down; these events only say what happened."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from .open_files import LoadedScene
    from .result_files import ResultInfo


@dataclass(frozen=True)
class SceneShown:
    """A new scene is on show (opened, or a result brought back by undo): the scene with its cameras, and the
    stylized result it is (None: not one)."""

    loaded: LoadedScene
    result: ResultInfo | None


@dataclass(frozen=True)
class RunReplacing:
    """The running engine's result is about to be replaced or dropped: ``action`` ("restart", "stop", "refine",
    "opening NAME", ...) names what replaces it (``ResultUndo`` keeps it as a step back)."""

    action: str


@dataclass(frozen=True)
class RunStarted:
    """An engine (re)started: it counts its versions from 0 again and the run before's progress goes."""


@dataclass(frozen=True)
class RunStopped:
    """The engine was stopped: what the stopped run showed in the panel goes (the view keeps what it shows)."""


Event = TypeVar("Event")
Handlers = dict[str, Callable[[dict[str, Any]], object]]  # a part's ``commands()``: command name -> what carries it out


class Events:
    """Subscribe to a kind of event; publish one to every subscriber of its kind, in the order they subscribed."""

    def __init__(self) -> None:
        self._handlers: dict[type, list[Callable[[Any], None]]] = defaultdict(list)

    def subscribe(self, kind: type[Event], handler: Callable[[Event], None]) -> None:
        """Call ``handler(event)`` for every ``kind`` published from now on."""
        self._handlers[kind].append(handler)

    def publish(self, event: object) -> None:
        """Hand ``event`` to its kind's subscribers, one after the other."""
        for handler in list(self._handlers[type(event)]):
            handler(event)
