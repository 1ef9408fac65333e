"""Shared pytest configuration.

Hypothesis profiles for the fuzz tests (``tests/test_fuzz_readers.py``), chosen with ``GSTYLE_FUZZ_PROFILE``:
"ci" (the default: few examples, derandomized so CI runs are repeatable) and "soak" (many random examples,
failures kept in the ``.hypothesis`` database). The fuzz tests apply the profile themselves, so other tests
keep hypothesis' defaults. Shared GL fixtures: ``ctx`` (standalone EGL context), ``window`` (headless studio
window of the module's W x H) and ``studio`` (a ring scene's studio in that window).

Precision: ``GSTYLE_PRECISION=fp32`` is set for the whole suite, so ``--precision auto`` resolves to fp32 without
timing anything (``gstyle_core/style/precision.py``). ``GSTYLE_FIGURES_WIDTH=64``: ``gstyle stylize``'s quality
figures are measured 64 px wide (``engine/build.evaluation_width``).

Thread count: ``GSTYLE_TEST_THREADS=N`` runs the suite with N torch threads (intra-op, set before each test, since
a test may change it) and N numba threads (``NUMBA_NUM_THREADS``, read when numba is imported), and sets
``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS`` for the subprocesses tests start. Unset: the libraries' own choice (one
thread per core). E.g. ``GSTYLE_TEST_THREADS=1 bash scripts/test.sh``. The header names the threads and the CPU.
"""

from __future__ import annotations

import os
import time
from datetime import timedelta
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

THREADS_ENV = "GSTYLE_TEST_THREADS"

# ``--precision auto`` (the default) resolves to fp32 in the suite and in the runs it starts: no result depends on
# whether the CPU does bf16 faster, and nothing is timed (tests/test_precision.py checks auto with a fake timer).
os.environ["GSTYLE_PRECISION"] = "fp32"
# ``gstyle stylize``'s quality figures at 64 px rather than 256 (its runs here are 32 px wide; at 256 px the figures
# took a third of the command-line tests' time): the same code at a smaller size (tests/test_figures_width.py).
os.environ.setdefault("GSTYLE_FIGURES_WIDTH", "64")
# The studio lowers its engine worker's priority (nice +10) so that its window stays smooth. Beside another test
# process at normal priority (scripts/test.sh runs two) such a worker got 3 % of a core and bench/ui.py's smoke run
# passed its 300 s: in a test process of pytest-xdist the workers the tests start keep the normal priority.
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("GSTYLE_WORKER_NICE", "0")


_THREADS_RAW = os.environ.get(THREADS_ENV, "").strip()
TEST_THREADS = int(_THREADS_RAW) if _THREADS_RAW.isdigit() and int(_THREADS_RAW) >= 1 else None
if TEST_THREADS is not None:  # before torch or numba is imported (test modules import them after this file)
    for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[_var] = str(TEST_THREADS)


def _set_library_threads(n: int) -> None:
    import numba
    import torch

    torch.set_num_threads(n)
    if numba.config.NUMBA_NUM_THREADS < n:  # numba was imported before this file set NUMBA_NUM_THREADS
        raise pytest.UsageError(f"{THREADS_ENV}={n}: numba's pool has {numba.config.NUMBA_NUM_THREADS} threads")
    numba.set_num_threads(n)  # the calling (main) thread's share of the pool


def pytest_configure(config) -> None:
    """Refuse a ``GSTYLE_TEST_THREADS`` that is not a positive integer (rather than silently using the defaults)."""
    if _THREADS_RAW and TEST_THREADS is None:
        raise pytest.UsageError(f"{THREADS_ENV}={_THREADS_RAW!r}: give a positive number of threads")


def pytest_report_header(config) -> list[str]:
    """The CPU and the thread counts the run uses (results may depend on both)."""
    from gstyle_core.machine import cpu_description

    threads = f"{TEST_THREADS} (torch, numba; {THREADS_ENV})" if TEST_THREADS else \
        f"library defaults ({THREADS_ENV} unset)"
    return [f"cpu: {cpu_description()}", f"threads: {threads}"]


@pytest.fixture(autouse=True)
def _thread_count():
    """With ``GSTYLE_TEST_THREADS``: every test starts at that many torch and numba threads."""
    if TEST_THREADS is not None:
        _set_library_threads(TEST_THREADS)
    yield


def _running(pid: str) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def pytest_collection_finish(session) -> None:
    """Before the first test, wait (at most 5 minutes) for scripts/test.sh's warm-up run (``GSTYLE_WARMUP_PID``: the
    demo's smoke run that compiles numba's kernels once), so that the test processes, started and collected
    meanwhile, do not compile the same kernels beside it."""
    pid = os.environ.get("GSTYLE_WARMUP_PID", "")
    deadline = time.monotonic() + 300
    while pid.isdigit() and _running(pid) and time.monotonic() < deadline:
        time.sleep(0.2)


def pytest_collection_modifyitems(config, items) -> None:
    """The tests marked ``slow`` first (in their order), the rest after: with two test processes
    (``scripts/test.sh``) the long ones start early and the short ones fill in at the end, rather than one process
    finishing a long test alone."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


FUZZ_PROFILE = os.environ.get("GSTYLE_FUZZ_PROFILE", "ci")
_SLOW_CHECKS = [HealthCheck.too_slow, HealthCheck.data_too_large]

settings.register_profile("ci", max_examples=30, deadline=timedelta(seconds=5), derandomize=True, database=None,
                          suppress_health_check=_SLOW_CHECKS, print_blob=True)
settings.register_profile("soak", max_examples=1000, deadline=timedelta(seconds=10),
                          suppress_health_check=_SLOW_CHECKS, print_blob=True)


@pytest.fixture(scope="module")
def ctx():
    """A standalone EGL OpenGL 3.3 context for the module (skips with the reason when there is none)."""
    moderngl = pytest.importorskip("moderngl")
    try:
        context = moderngl.create_standalone_context(backend="egl", require=330)
    except Exception as exc:  # noqa: BLE001
        pytest.skip(f"no EGL OpenGL 3.3 context: {exc}")
    yield context
    context.release()


@pytest.fixture
def window(request):
    """A headless studio window (glfw NULL platform + EGL) of the test module's ``W`` x ``H``."""
    pytest.importorskip("imgui_bundle")
    from app.window import DisplayUnavailableError, open_window

    try:
        win = open_window(request.module.W, request.module.H, headless=True)
    except DisplayUnavailableError as exc:
        pytest.skip(f"no headless GL window (glfw NULL + EGL): {exc}")
    yield win
    win.close()


@pytest.fixture
def studio(window, monkeypatch, tmp_path):
    """``fakes.ring_studio`` in the module's headless window (the fake engine in a worker thread, its cache folder in
    the test's), closed at the end. A module that needs another studio defines its own ``studio`` fixture."""
    from fakes import ring_studio

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    app = ring_studio(window, tmp_path)
    yield app
    app.close(timeout=30)


@pytest.fixture
def no_clip_weights(monkeypatch):
    """No CLIP weights anywhere: runs get the coarse substitute (or no CLIP term), as on a machine without them."""
    from gstyle_core.style import clip as clip_module

    monkeypatch.setattr(clip_module, "clip_search_paths", lambda: [])
    monkeypatch.delenv(clip_module.CLIP_ENV, raising=False)


@pytest.fixture(scope="module")
def vgg():
    """VGG-16 block 1-3 with random weights (seed 0), in eval mode: the loss definitions do not depend on them."""
    import torch

    from gstyle_core.style.vgg import VGGFeatures

    torch.manual_seed(0)
    return VGGFeatures().eval()


@pytest.fixture
def started_bridges():
    """``start(bridge_class, factory, config, quit_timeout)``: a worker bridge of that class (the spawned process's
    ``WorkerBridge`` or the thread's ``ThreadWorkerBridge``) on the engine ``factory`` builds from ``config``,
    started; every bridge started is quit at the test's end."""
    bridges = []

    def start(bridge_class, factory, config: dict, quit_timeout: float = 5):
        bridge = bridge_class(factory, config)
        bridge.start()
        bridges.append((bridge, quit_timeout))
        return bridge

    yield start
    for bridge, timeout in bridges:
        bridge.quit(timeout=timeout)
