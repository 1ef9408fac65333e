"""``gstyle batch --plan plan.toml``: runs whose settings vary. The plan's top level holds ``scenes``, ``styles`` and
``gstyle stylize`` options shared by every run; each ``[[run]]`` table has a ``name`` and may give its own scenes,
styles and options. Every run × scene × painting is a job (``SCENE__PAINTING__RUN.ply``). An option is written as on
the command line without its dashes (``preset = "final"``, ``working-width = 512``, ``keep-colours = true``,
``refine-widths = [512, 1024]``); a run's own option wins over the plan's, which wins over the command line's.
Relative paths in the plan are read from the plan file's folder. A key the plan may not hold, or a value the option
refuses, is one line naming the key and the plan file.
"""

from __future__ import annotations

import argparse
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import GStyleError

# the batch's own options and the ones every job sets itself: not for a plan
NOT_IN_PLANS = ("scene", "style", "out", "force", "resume", "threads", "jobs", "plan", "ray", "help")
RUN_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,39}")


@dataclass
class Run:
    """One run of a batch: its name ("" without a plan), scenes, paintings and ``gstyle stylize`` options."""

    name: str
    scenes: list[str]
    styles: list[str]
    options: list[str] = field(default_factory=list)


class _Refused(Exception):
    """argparse's error, raised instead of exiting."""


class _CheckingParser(argparse.ArgumentParser):
    def error(self, message: str):  # noqa: D102 - argparse's hook
        raise _Refused(message)


def stylize_parser(add_stylize_arguments: Callable[[argparse.ArgumentParser], None]) -> argparse.ArgumentParser:
    """``gstyle stylize``'s options (added by ``add_stylize_arguments``), with errors raised (``_Refused``) rather
    than exiting."""
    p = _CheckingParser(add_help=False, allow_abbrev=False, exit_on_error=False)
    add_stylize_arguments(p)
    return p


def batch_runs(args: argparse.Namespace, cli_options: list[str],
               add_stylize_arguments: Callable[[argparse.ArgumentParser], None]) -> list[Run]:
    """The batch's runs: the plan's (``--plan``), else one of ``--scenes`` × ``--styles``; ``cli_options``: the
    command line's ``gstyle stylize`` options, given to every job; a plan's are checked against
    ``add_stylize_arguments``'s."""
    plan = getattr(args, "plan", None)
    if plan is None:
        if not args.scenes or not args.styles:
            raise GStyleError("give the scenes with --scenes and the paintings with --styles (or a --plan)")
        return [Run("", list(args.scenes), list(args.styles), list(cli_options))]
    return read_plan(Path(plan), cli_options, args.scenes or [], args.styles or [], add_stylize_arguments)


def read_plan(path: Path, cli_options: list[str], scenes: list[str], styles: list[str],
              add_stylize_arguments: Callable[[argparse.ArgumentParser], None]) -> list[Run]:
    """The runs of the plan file at ``path``; ``scenes`` and ``styles`` (the command line's) are the defaults of a
    plan that names none."""
    try:
        with open(path, "rb") as fh:
            plan = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise GStyleError(f"{path}: not a TOML plan: {exc}") from None
    parser, folder = stylize_parser(add_stylize_arguments), path.parent
    tables = plan.pop("run", None)
    no_runs = tables is None  # the top level is the one run, without a name
    tables = [{}] if no_runs else tables
    if not isinstance(tables, list) or not tables or not all(isinstance(t, dict) for t in tables):
        raise GStyleError(f"{path}: run: give each run as a [[run]] table")
    top = _Table(path, "", folder)
    shared_scenes = top.paths(plan, "scenes", scenes)
    shared_styles = top.paths(plan, "styles", styles)
    shared = top.options(parser, plan)
    runs, seen = [], set()
    for k, table in enumerate(tables, start=1):
        name = table.pop("name", "" if no_runs else None)
        where = f"run {k}"
        if name is None or not isinstance(name, str) or name and not RUN_NAME.fullmatch(name):
            raise GStyleError(f"{path}: {where}: name: give each run a name of letters, digits, '.', '_' or '-' "
                              f"(at most 40), got {name!r}")
        if name in seen:
            raise GStyleError(f"{path}: {where}: name: two runs are named {name!r}")
        seen.add(name)
        own = _Table(path, f"run {name!r}: " if name else f"{where}: ", folder)
        run = Run(name, own.paths(table, "scenes", shared_scenes), own.paths(table, "styles", shared_styles))
        run.options = [*cli_options, *shared, *own.options(parser, table)]
        for key, given in (("scenes", run.scenes), ("styles", run.styles)):
            if not given:
                raise GStyleError(f"{path}: {own.where}{key}: none given (in the run, the plan's top level or "
                                  f"--{key})")
        runs.append(run)
    return runs


@dataclass
class _Table:
    """Reads the keys of one table of the plan at ``path`` (``where``: which, for its errors)."""

    path: Path
    where: str
    folder: Path

    def fail(self, key: str, why: str) -> GStyleError:
        return GStyleError(f"{self.path}: {self.where}{key}: {why}")

    def paths(self, table: dict, key: str, default: list[str]) -> list[str]:
        """The list of files under ``key`` (relative ones from the plan's folder), else ``default``."""
        if key not in table:
            return list(default)
        value = table.pop(key)
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not value or not all(isinstance(v, str) and v for v in value):
            raise self.fail(key, f"give a list of files, got {value!r}")
        return [v if Path(v).is_absolute() else str(self.folder / v) for v in value]

    def options(self, parser: argparse.ArgumentParser, table: dict) -> list[str]:
        """The ``gstyle stylize`` options of the table's remaining keys, each checked as the command line would."""
        tokens = []
        for key, value in table.items():
            flag = "--" + key.replace("_", "-")
            action = parser._option_string_actions.get(flag)  # noqa: SLF001 - argparse's table of options
            if action is None or key.replace("_", "-") in NOT_IN_PLANS or isinstance(value, dict):
                raise self.fail(key, "not a gstyle stylize option a plan can set (docs/batch.md)")
            if action.nargs == 0:  # a switch: true or false
                if not isinstance(value, bool):
                    raise self.fail(key, f"give true or false, got {value!r}")
                tokens += [flag] if value else []
                continue
            if isinstance(value, bool):
                raise self.fail(key, f"give a value, not {str(value).lower()}")
            text = ",".join(map(str, value)) if isinstance(value, list) else str(value)
            try:
                parser.parse_args([f"{flag}={text}"])
            except (_Refused, argparse.ArgumentError) as exc:
                raise self.fail(key, str(exc)) from None
            tokens.append(f"{flag}={text}")
        return tokens
