"""``python -m gstyle_core.cli``: the ``gstyle`` command (what ``gstyle batch``'s pool jobs run)."""

from .main import main

main()
