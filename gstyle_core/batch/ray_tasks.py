"""``gstyle batch --ray ADDRESS``: each job a Ray task (``pip install 'gstyle-studio[ray]'``; Ray is imported only
here, only with ``--ray``).

The driver (the ``gstyle batch`` process) connects with ``ray.init(address=ADDRESS)`` (``auto``: the cluster running
on this machine or at ``RAY_ADDRESS``; ``local``: a new one here, stopped at the end; ``HOST:PORT`` or
``ray://HOST:PORT``: that cluster), or keeps the connection its process already has. Each task declares
``num_cpus`` = the job's threads and ``num_gpus`` = 1 when the job computes on a GPU. The scene and the painting go to
the worker as bytes (each file put in Ray's object store once); the worker writes them into a temporary folder and
runs the same ``gstyle stylize`` subprocess as the local pool (``batch_jobs.start``, the same argv with the temporary
paths) and sends back OUT.ply, OUT.json, the before/after pictures and the log. The driver writes them into the batch's
folder as one group, the scene last (OUT.json's paths renamed to the driver's), as soon as each job ends: a
killed batch or a lost worker loses no finished job, and a rerun skips them as the local pool does. A job that did
not finish starts again on the rerun (its checkpoint stayed on the worker, in a temporary place).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import tempfile
import time
from pathlib import Path

from ..atomic import atomic_write_bytes
from ..errors import GStyleError
from ..outputs import STYLIZE_COMPANIONS, companions
from . import jobs as batch_jobs
from .jobs import DEFAULT_THREADS_PER_JOB, Job, check_counts, finish, job_argv, progress

TAILS = (*STYLIZE_COMPANIONS, ".ply")  # what a job sends back, the scene last, as ``gstyle stylize`` writes them
WAIT_SECONDS = 1.0
NEEDS_RAY = "--ray needs the 'ray' package: pip install 'gstyle-studio[ray]' (or pip install 'ray>=2.9')"


def import_ray():
    """The ``ray`` module, or a one-line error naming the extra to install."""
    try:
        import ray
    except ImportError:
        raise GStyleError(NEEDS_RAY) from None
    return ray


def connect(ray, address: str) -> bool:
    """Connect to the cluster at ``address`` as ``ray.init(address=...)`` reads it, unless this process is connected
    already; True when this call connected (the batch disconnects at its end)."""
    if ray.is_initialized():
        return False
    starts = address == "local"
    try:
        ray.init(address=address, log_to_driver=False, logging_level="ERROR",
                 **({"include_dashboard": False} if starts else {}))
    except (ConnectionError, ValueError, RuntimeError) as exc:
        raise GStyleError(f"--ray {address}: cannot connect to a Ray cluster: {' '.join(str(exc).split())}") from None
    return True


def uses_gpu(args: argparse.Namespace, cluster: dict) -> bool:
    """Whether each job asks for a GPU: ``--device cuda``, or the default device on a cluster that has GPUs."""
    device = getattr(args, "device", None)
    return device == "cuda" or device in (None, "auto") and cluster.get("GPU", 0) >= 1


def run_on_ray(jobs: list[Job], pending: list[Job], args: argparse.Namespace) -> None:
    """Run the pending jobs as Ray tasks, writing each one's outputs into the batch's folder as it ends."""
    if not pending:
        print(f"batch: {len(jobs)} jobs, {len(jobs)} done already; nothing to run", file=sys.stderr)
        return
    check_counts(args)
    ray = import_ray()
    connected = connect(ray, args.ray)
    try:
        cluster = ray.cluster_resources()
        threads = args.threads or DEFAULT_THREADS_PER_JOB
        gpus = 1 if uses_gpu(args, cluster) else 0
        slots = max(1, int(cluster.get("GPU", 0)) if gpus else int(cluster.get("CPU", 1) // threads))
        print(f"batch: {len(jobs)} jobs, {len(jobs) - len(pending)} done already; {len(pending)} to run on the Ray "
              f"cluster ({int(cluster.get('CPU', 0))} CPUs, {int(cluster.get('GPU', 0))} GPUs), {threads} threads "
              f"{'and a GPU ' if gpus else ''}each", file=sys.stderr)
        task = ray.remote(run_job).options(num_cpus=threads, num_gpus=gpus)
        files: dict[str, object] = {}  # each input file put in the object store once

        def shipped(path: str):
            if path not in files:
                files[path] = ray.put(Path(path).read_bytes())
            return files[path]

        refs = {}
        for job in pending:
            refs[task.remote(job.options, Path(job.scene).name, shipped(job.scene), Path(job.painting).name,
                             shipped(job.painting), job.out.name, threads, batch_jobs.WORKER[1:])] = job
        collect(ray, jobs, refs, slots)
    finally:
        if connected:
            ray.shutdown()


def collect(ray, jobs: list[Job], refs: dict, slots: int) -> None:
    """Wait for the tasks, writing each job's files as it ends; Ctrl+C cancels the tasks still running (the finished
    jobs are written)."""
    t0, left = time.perf_counter(), list(refs)
    for job in list(refs.values())[:slots]:
        job.status = "running"
    progress(jobs, slots)
    try:
        while left:
            ready, left = ray.wait(left, num_returns=1, timeout=WAIT_SECONDS)
            for ref in ready:
                job = refs[ref]
                try:
                    result = ray.get(ref)
                except ray.exceptions.RayError as exc:  # the worker or its node was lost (after Ray's retries)
                    result = {"code": 1, "seconds": time.perf_counter() - t0, "files": {},
                              "log": f"gstyle batch: the Ray task failed: {first_line(exc)}\n".encode()}
                write_back(job, result)
                waiting = [j for j in refs.values() if j.status == "pending"]
                if waiting:
                    waiting[0].status = "running"
                progress(jobs, slots)
    except KeyboardInterrupt:
        for ref in left:
            ray.cancel(ref, force=True)
        raise


def first_line(exc: BaseException) -> str:
    """An exception's first non-empty line."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    return lines[0] if lines else type(exc).__name__


def write_back(job: Job, result: dict) -> None:
    """Write a task's log, and its outputs as one group (the scene last), into the batch's folder."""
    from ..outputs import OutputGroup

    atomic_write_bytes(job.log, result["log"])
    code, sent = result["code"], result["files"]
    if code == 0:
        if set(sent) != set(TAILS):
            code = 1
            atomic_write_bytes(job.log, result["log"] + b"gstyle batch: the job sent back no outputs\n")
        else:
            sent = {**sent, TAILS[0]: relocated(sent[TAILS[0]], job)}
            with OutputGroup() as group:
                for tail, path in zip(TAILS, [*companions(job.out, STYLIZE_COMPANIONS), job.out], strict=True):
                    group.write(path, lambda tmp, data=sent[tail]: atomic_write_bytes(tmp, data))
    finish(job, code, result["seconds"])


def relocated(summary: bytes, job: Job) -> bytes:
    """OUT.json with the worker's temporary input paths replaced by the driver's (the files the job was made from)."""
    data = json.loads(summary)
    data["scene"], data["source_scene"] = job.scene, str(Path(job.scene).resolve())
    data["style"] = job.painting
    for entry in data.get("styles") or []:
        entry["path"] = job.painting
    return json.dumps(data, indent=2).encode()


def run_job(options: list[str], scene_name: str, scene: bytes, painting_name: str, painting: bytes, out_name: str,
            threads: int, worker: list[str]) -> dict:
    """The Ray task: write the inputs into a temporary folder, run the job there as the local pool does (``worker``:
    the command after the Python executable) and return its exit status, seconds, output files and log."""
    from ..engine.checkpoint import stylize_checkpoint_path
    from ..engine.kept_runs import note_path, result_state_path

    with tempfile.TemporaryDirectory(prefix="gstyle-batch-") as tmp:
        folder = Path(tmp)
        inputs = []
        for sub, name, data in (("scenes", scene_name, scene), ("styles", painting_name, painting)):
            (folder / sub).mkdir()
            inputs.append(folder / sub / name)
            inputs[-1].write_bytes(data)
        out = folder / "out" / out_name
        job = Job(str(inputs[0]), str(inputs[1]), out, job_argv(str(inputs[0]), str(inputs[1]), options, out))
        job.argv += ["--threads", str(threads)]
        job.log.parent.mkdir(parents=True)
        _job, proc, t0, log = batch_jobs.start(job, 0, 0, threads, [sys.executable, *worker])
        try:
            code = proc.wait()
        except BaseException:  # cancelled: the job stops with it
            proc.kill()
            proc.wait()
            raise
        finally:
            log.close()
            state = result_state_path(out)
            for kept in (stylize_checkpoint_path(out), state, note_path(state)):  # keyed by this temporary --out
                with contextlib.suppress(OSError):
                    kept.unlink(missing_ok=True)
        seconds = time.perf_counter() - t0
        files = {tail: path.read_bytes() for tail, path in zip(TAILS, [*companions(out, STYLIZE_COMPANIONS), out],
                                                               strict=True) if path.is_file()} if code == 0 else {}
        return {"code": code, "seconds": seconds, "files": files, "log": job.log.read_bytes()}
