"""One parsed ``gstyle`` command run under the command line's error contract: ``GStyleError`` and bad paths become
one line and exit status 2 (writes that fail are ``OutputWriteError``s: ``cannot write PATH: CAUSE``), Ctrl+C exit
status 130, any other error one line naming its crash log and exit status 1. ``cli.run`` and ``gstyle batch``'s jobs
run in its own process (``cli/batch.py``) both run their commands through ``run_parsed``.
"""

from __future__ import annotations

import argparse
import sys

from ..errors import GStyleError


def run_parsed(args: argparse.Namespace) -> int:
    """Run ``args.func(args)`` (``args.command`` names it in messages, ``args.argv`` is what was typed) and return
    its exit status under the contract above."""
    try:
        return int(args.func(args) or 0)
    except GStyleError as exc:
        print(f"gstyle {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a path that cannot be read (or another system error): one line all the same
        where = f": {exc.filename}" if exc.filename else ""
        print(f"gstyle {args.command}: error: {' '.join(str(exc.strerror or exc).split())}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"gstyle {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - a bug: one line for the artist, its traceback in a crash log
        from ..crash import crash_line

        print(crash_line(args.command, exc, args.argv), file=sys.stderr)
        return 1
