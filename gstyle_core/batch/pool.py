"""``gstyle batch``: every scene after every painting, each pair one ``gstyle stylize`` job with its own OUT.ply,
OUT.json and pictures in the output folder; jobs already finished are skipped, an interrupted one resumes, a failed
one is one line and the others go on. Ends with ``batch.csv`` (a row per job) and ``contact_sheet.png``.

Jobs run in the calling process one after another (``--jobs 1``) or as ``python -m gstyle_core.cli stylize``
subprocesses, at most ``--jobs`` at a time (one per CUDA GPU, each seeing only its own, when torch sees GPUs), or
as Ray tasks with ``--ray ADDRESS`` (``ray_tasks.py``). ``--plan plan.toml`` varies settings between runs
(``plan.py``). The command (its arguments, ``gstyle stylize`` in this process) is ``gstyle_core/cli/batch.py``.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ..engine.checkpoint import stylize_checkpoint_path
from ..errors import GStyleError
from ..outputs import BATCH_TABLE, output_base
from .jobs import (
    DEFAULT_THREADS_PER_JOB,
    POLL_SECONDS,
    Job,
    check_counts,
    finish,
    job_argv,
    progress,
    start,
)
from .report import write_contact_sheet, write_csv

AddArguments = Callable[[argparse.ArgumentParser], None]  # adds ``gstyle stylize``'s options to a parser
RunJob = Callable[[list[str]], int]  # runs one job's ``gstyle stylize`` argv here: its exit status


def stylize_options(argv: list[str]) -> list[str]:
    """The ``gstyle stylize`` options among ``gstyle batch``'s arguments ``argv`` (the batch's own taken out)."""
    pre = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    pre.add_argument("--scenes", nargs="+")
    pre.add_argument("--styles", nargs="+")
    for name in ("--jobs", "--threads", "--out", "--plan", "--ray"):
        pre.add_argument(name)
    pre.add_argument("--resume", action="store_true")
    args = argv[1:] if argv and argv[0] == "batch" else argv
    return pre.parse_known_args(args)[1]


def plan_jobs(args: argparse.Namespace, out_dir: Path, add_stylize_arguments: AddArguments) -> list[Job]:
    """A job per run, scene and painting, named ``SCENE__PAINTING.ply`` (stems; ``SCENE__PAINTING__RUN.ply`` with a
    plan); finished ones (OUT.ply exists, written last) are marked done already unless ``--force``; an interrupted
    one (its checkpoint exists) gets ``--resume``; ``add_stylize_arguments``: ``gstyle stylize``'s options, which
    a plan's are checked against."""
    from .plan import batch_runs

    if args.scene is not None or args.style:
        raise GStyleError("give the scenes with --scenes and the paintings with --styles")
    jobs, names = [], set()
    for run in batch_runs(args, stylize_options(getattr(args, "argv", [])), add_stylize_arguments):
        for scene in run.scenes:
            for painting in run.styles:
                name = "__".join(x for x in (output_base(Path(scene).name).name, Path(painting).stem, run.name) if x)
                if name in names:
                    raise GStyleError(f"two jobs would both write {out_dir / name}.ply: give scenes and paintings "
                                      "different names")
                names.add(name)
                out = out_dir / f"{name}.ply"
                argv = job_argv(scene, painting, run.options, out)
                if stylize_checkpoint_path(out).exists() and not args.force:
                    argv.append("--resume")
                done = out.exists() and not args.force
                jobs.append(Job(scene, painting, out, argv, "done already" if done else "pending", run=run.name,
                                options=list(run.options)))
    return jobs


def pool_size(args: argparse.Namespace, pending: int) -> tuple[int, int, int]:
    """Jobs at a time, torch threads per job and CUDA GPUs to spread them over (0: none)."""
    from ..machine import usable_cores

    check_counts(args)
    cores, gpus = usable_cores(), cuda_gpus(args)
    jobs = args.jobs or gpus or max(1, cores // (args.threads or DEFAULT_THREADS_PER_JOB))
    jobs = max(1, min(jobs, pending))
    return jobs, args.threads or max(1, cores // jobs), gpus


def cuda_gpus(args: argparse.Namespace) -> int:
    """The CUDA GPUs torch sees, unless the jobs are asked to run elsewhere (0 then)."""
    if getattr(args, "device", None) in ("cpu", "mps"):
        return 0
    import torch

    return torch.cuda.device_count()


def run_batch(args: argparse.Namespace, add_stylize_arguments: AddArguments, stylize_here: RunJob) -> int:
    """Run a batch: the jobs, a progress line per change, then batch.csv and contact_sheet.png; the command line
    gives ``gstyle stylize``'s options (``add_stylize_arguments``) and how one job runs in this process
    (``stylize_here``: its argv -> exit status)."""
    out_dir = Path(args.out)
    jobs = plan_jobs(args, out_dir, add_stylize_arguments)
    pending = [job for job in jobs if job.status == "pending"]
    if getattr(args, "ray", None):
        from .ray_tasks import run_on_ray

        (out_dir / "logs").mkdir(parents=True, exist_ok=True)
        run_on_ray(jobs, pending, args)
        return write_results(jobs, out_dir)
    slots, threads, gpus = pool_size(args, len(pending)) if pending else (1, 0, 0)
    for job in pending:
        job.argv += ["--threads", str(threads)]
    (out_dir / "logs").mkdir(parents=True, exist_ok=True)
    already = len(jobs) - len(pending)
    where = "in this process" if slots == 1 else f"{slots} at a time" + (f" over {gpus} GPUs" if gpus else "")
    plan = f"{len(pending)} to run {where}, {threads} threads each" if pending else "nothing to run"
    print(f"batch: {len(jobs)} jobs, {already} done already; {plan}", file=sys.stderr)
    if slots == 1:
        run_in_process(jobs, pending, stylize_here)
    else:
        run_in_pool(jobs, pending, slots, gpus, threads)
    return write_results(jobs, out_dir)


def write_results(jobs: list[Job], out_dir: Path) -> int:
    """batch.csv and contact_sheet.png, the last line; the batch's exit status (1 if a job failed)."""

    written = [write_csv(jobs, out_dir / BATCH_TABLE), write_contact_sheet(jobs, out_dir / "contact_sheet.png")]
    failed = sum(job.status == "failed" for job in jobs)
    print(f"batch: {len(jobs) - failed} done, {failed} failed; wrote {', '.join(map(str, written))}")
    return 1 if failed else 0


def run_in_process(jobs: list[Job], pending: list[Job], stylize_here: RunJob) -> None:
    """Each job through ``stylize_here`` in this process, its output to its log; Ctrl+C stops the batch (the job
    keeps its checkpoint: a rerun resumes it)."""
    for job in pending:
        job.status, t0 = "running", time.perf_counter()
        progress(jobs, 1)
        with open(job.log, "w", encoding="utf-8") as log, contextlib.redirect_stdout(log), \
                contextlib.redirect_stderr(log):
            code = stylize_here(job.argv)
        finish(job, code, time.perf_counter() - t0)
        if code == 130:
            raise KeyboardInterrupt
        progress(jobs, 1)


def run_in_pool(jobs: list[Job], pending: list[Job], slots: int, gpus: int, threads: int) -> None:
    """The jobs as subprocesses, ``slots`` at a time (slot k sees GPU k % gpus alone), each with ``threads`` threads
    in every thread pool; Ctrl+C lets the running ones save their checkpoints before the batch stops."""
    queue, running = list(pending), {}
    try:
        while queue or running:
            for slot in [s for s in range(slots) if s not in running][: len(queue)]:
                running[slot] = start(queue.pop(0), slot, gpus, threads)
                progress(jobs, slots)
            for slot, (job, proc, t0, log) in list(running.items()):
                if proc.poll() is not None:
                    log.close()
                    finish(job, proc.returncode, time.perf_counter() - t0)
                    del running[slot]
                    progress(jobs, slots)
            time.sleep(POLL_SECONDS)
    except KeyboardInterrupt:
        for _job, proc, _, log in running.values():
            proc.wait()
            log.close()
        raise


