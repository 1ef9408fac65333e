"""The ``gstyle`` command line: every subcommand's parser and driver (``main.py`` dispatches; ``stylize``, ``batch``,
``render``, ``fit``, ``cache`` each have a module; ``commands.py`` is the error contract they all run under). It
imports the engine (``gstyle_core/engine``) and the batch (``gstyle_core/batch``); neither imports it."""

from .main import build_parser, main, run

__all__ = ["build_parser", "main", "run"]
