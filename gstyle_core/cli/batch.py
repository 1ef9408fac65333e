"""``gstyle batch``'s arguments and its command: every scene after every painting as ``gstyle stylize`` jobs, run by
``gstyle_core/batch`` (the plan, the pool, Ray, the report), with this command line's ``stylize`` for each job."""

from __future__ import annotations

import argparse

from ..batch.jobs import DEFAULT_THREADS_PER_JOB
from ..batch.pool import run_batch
from .commands import run_parsed
from .stylize import add_stylize_arguments, stylize_command


def add_batch_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``gstyle batch``: those of ``gstyle stylize`` (given to every job) and the batch's own; ``p``
    resolves conflicts (``--out`` and ``--threads`` are the batch's)."""
    add_stylize_arguments(p)
    p.add_argument("--scenes", nargs="+", default=None, metavar="SCENE", help="scene files, one row each")
    p.add_argument("--styles", nargs="+", default=None, metavar="IMAGE", help="paintings, one column each")
    p.add_argument("--plan", default=None, metavar="PLAN.toml",
                   help="runs whose settings vary, each with its scenes and paintings (docs/batch.md); the command "
                        "line's stylize options go to every job, a run's own win")
    p.add_argument("--ray", default=None, metavar="ADDRESS",
                   help="run each job as a task on a Ray cluster: auto, local, HOST:PORT or ray://HOST:PORT, as "
                        "ray.init(address=...) reads it (needs the 'ray' extra)")
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="jobs at a time (default: one per CUDA GPU, else cores // --threads); 1 runs them in this "
                        "process")
    p.add_argument("--threads", type=int, default=None,
                   help=f"torch threads per job (default: cores // --jobs, or {DEFAULT_THREADS_PER_JOB} without it)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder of the results: DIR/SCENE__PAINTING.ply with its .json and pictures, batch.csv, "
                        "contact_sheet.png, logs/")

def stylize_in_process(argv: list[str]) -> int:
    """``gstyle stylize`` with a job's arguments (``batch.jobs.job_argv``: "stylize" first) in this process, under
    the command line's error contract (``commands.run_parsed``): its exit status."""
    parser = argparse.ArgumentParser(prog="gstyle stylize")
    add_stylize_arguments(parser)
    args = parser.parse_args(argv[1:])
    args.command, args.func, args.argv = "stylize", stylize_command, list(argv)
    return run_parsed(args)


def batch_command(args: argparse.Namespace) -> int:
    """Run ``gstyle batch`` (``batch.pool.run_batch``): its exit status, 1 if a job failed."""
    return run_batch(args, add_stylize_arguments, stylize_in_process)
