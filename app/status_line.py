"""The studio's status line (the panel's ``status``): its one owner. Every part says what happened through it."""

from __future__ import annotations

from .panels import PanelState


class StatusLine:
    """Writes ``panel.status``; remembers a line about the running engine (``say_of_run``) so that it goes when the
    run ends (``end_run``)."""

    def __init__(self, panel: PanelState) -> None:
        self.panel = panel
        self._run_status = ""  # the status line, when it describes the running engine (its resume, a move)

    @property
    def text(self) -> str:
        """What the status line says now."""
        return self.panel.status

    def say(self, text: str) -> None:
        """Show ``text`` (the line before goes)."""
        self.panel.status = text

    def tell(self, text: str) -> None:
        """Show ``text``, and print the same line in the terminal."""
        self.say(text)
        print(f"gstyle-studio: {text}", flush=True)

    def add(self, text: str) -> None:
        """Add ``text`` to the end of the line shown."""
        self.panel.status += text

    def clear_if(self, prefixes: tuple[str, ...]) -> None:
        """Clear the line when it starts with one of ``prefixes`` (it no longer holds)."""
        if self.panel.status.startswith(prefixes):
            self.panel.status = ""

    def say_of_run(self, line: str, in_terminal: bool = False) -> None:
        """A status line about the running engine: cleared when that run ends (``end_run``) if still shown;
        ``in_terminal``: printed there too."""
        (self.tell if in_terminal else self.say)(line)
        self._run_status = line

    def end_run(self) -> None:
        """The engine's run ends (a restart, a stop, another scene): a status line that described it goes too."""
        if self._run_status and self.panel.status == self._run_status:
            self.panel.status = ""
        self._run_status = ""
