"""The jobs of ``gstyle batch`` and their bookkeeping, shared by the local pool (``batch.py``), the Ray tasks
(``batch_ray.py``) and the batch's report (``batch_report.py``): a job, its ``gstyle stylize`` argv, starting one as a
subprocess (``WORKER``), recording how it ended, the progress line."""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import GStyleError
from ..outputs import companion

# jobs = cores // threads; a 2-thread job slowed 12x on a shared machine (docs/notes/batch-speed.md)
DEFAULT_THREADS_PER_JOB = 1
WORKER = [sys.executable, "-m", "gstyle_core.cli"]  # the command a pool job runs: ``WORKER + job.argv``
POLL_SECONDS = 0.2


@dataclass
class Job:
    """One scene after one painting: its ``gstyle stylize`` arguments and how it went."""

    scene: str
    painting: str
    out: Path
    argv: list[str]
    status: str = "pending"  # pending, running, done, done already, failed
    seconds: float | None = None
    line: str = ""  # a failed job's last line (its error or crash line)
    run: str = ""  # the plan's run it belongs to ("" without a plan)
    options: list[str] = field(default_factory=list)  # its ``gstyle stylize`` options (``job_argv``)

    @property
    def log(self) -> Path:
        """The job's stdout and stderr."""
        return self.out.parent / "logs" / (self.out.stem + ".log")


def job_argv(scene: str, painting: str, options: list[str], out: Path) -> list[str]:
    """The ``gstyle stylize`` arguments of one job."""
    return ["stylize", scene, "--style", painting, *options, "--out", str(out)]


def check_counts(args: argparse.Namespace) -> None:
    """``--jobs`` and ``--threads``, when given, at least 1 (a one-line error otherwise)."""
    if args.jobs is not None and args.jobs < 1 or args.threads is not None and args.threads < 1:
        raise GStyleError("--jobs and --threads must be at least 1")


def start(job: Job, slot: int, gpus: int, threads: int,
          worker: list[str] | None = None) -> tuple[Job, subprocess.Popen, float, object]:
    """Start ``job`` as a subprocess (``worker + job.argv``, default ``WORKER``) writing to its log; numba's and
    OpenMP's pools get ``threads`` threads too, as torch does (``--threads``), so that jobs side by side do not
    oversubscribe the cores."""
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads))
    if gpus:
        env["CUDA_VISIBLE_DEVICES"] = str(slot % gpus)
    log = open(job.log, "w", encoding="utf-8")  # noqa: SIM115 - closed when the job ends
    job.status = "running"
    proc = subprocess.Popen([*(worker or WORKER), *job.argv], stdout=log, stderr=subprocess.STDOUT, env=env)
    return job, proc, time.perf_counter(), log


def finish(job: Job, code: int, seconds: float) -> None:
    """Record how ``job`` ended; a failure is one line on stderr."""
    job.seconds = seconds
    if code == 0:
        job.status = "done"
        return
    job.status, job.line = "failed", failure_line(job.log, code)
    print(f"batch: {Path(job.scene).name} after {Path(job.painting).name} failed: {job.line}", file=sys.stderr)


def failure_line(log: Path, code: int) -> str:
    """The last ``gstyle ...`` line of a failed job's log (its one-line error), else its last line."""
    try:
        text = log.read_text(encoding="utf-8", errors="replace")
    except OSError:
        text = ""
    lines = [line.strip() for line in text.replace("\r", "\n").splitlines() if line.strip()]
    said = [line for line in lines if line.startswith("gstyle ")]
    return (said or lines or [f"exit status {code}"])[-1]


def progress(jobs: list[Job], slots: int) -> None:
    """The batch's line: jobs done, running, failed, and the time left from the median of the jobs finished now."""
    count = {s: sum(job.status == s for job in jobs) for s in ("done", "done already", "running", "failed", "pending")}
    times = [job.seconds for job in jobs if job.status == "done" and job.seconds is not None]
    left = count["pending"] + count["running"]
    eta = "-" if not times or not left else duration(statistics.median(times) * -(-left // slots))
    print(f"batch: {count['done'] + count['done already']} of {len(jobs)} done ({count['done already']} already), "
          f"{count['running']} running, {count['failed']} failed, ETA {eta}", file=sys.stderr)


def duration(seconds: float) -> str:
    """``seconds`` as ``1 h 02 min``, ``3 min 05 s`` or ``42 s``."""
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    return f"{s // 60} min {s % 60:02d} s" if s >= 60 else f"{s} s"


def summary_path(job: Job) -> Path:
    """The job's OUT.json."""
    return companion(job.out, ".json")
