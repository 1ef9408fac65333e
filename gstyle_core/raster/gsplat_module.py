"""gsplat's compiled CUDA module: load one built before, or build it once (minutes) and keep it in the cache.

gsplat from PyPI is pure Python; its CUDA code compiles on first use through torch's JIT extension builder
(``gsplat/cuda/_backend.py``). Left alone, that build happens silently deep inside the first render and takes
minutes. Here it is made explicit:

- ``built_module_path()`` names the file a build is kept in: one per torch version, CUDA version, gsplat version
  and GPU architecture, under the G-Style cache (``paths.cache_dir()/gsplat``), or ``$GSTYLE_GSPLAT_MODULE``.
- ``ensure_gsplat(log)`` loads that file when it is there (it registers it as ``gsplat.csrc``, the name gsplat
  imports first), else builds for this card's architecture only (``TORCH_CUDA_ARCH_LIST``), telling the user once
  that the first run builds it, and copies the result to the cache for every later run.
- ``RasterizerSetup`` does that once per run, before its first render and outside any step's own time, and words
  it for a UI beforehand (``note``): a studio shows "building ..." while the build runs, not a frozen first step.

Nothing here falls back to the CPU: a failed build raises :class:`GsplatUnavailable` with the reason.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import os
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ..device import DeviceFailure
from ..paths import cache_dir

MODULE_NAME = "gsplat_cuda"
BUILD_NOTE = "building gsplat's rasterizer for this GPU: a few minutes, the first run only"  # the status's 2 lines


class GsplatUnavailable(DeviceFailure):
    """gsplat or its CUDA module cannot be used here (not installed, no CUDA, or its build failed)."""


def _versions() -> tuple[str, str, str]:
    import torch

    try:
        import gsplat
    except ImportError as error:
        raise GsplatUnavailable(
            "gsplat is not installed: run scripts/setup.sh on this machine (it installs the 'cuda' extra where "
            "nvidia-smi finds a GPU), or pip install gsplat==1.5.3"
        ) from error
    return torch.__version__, str(torch.version.cuda), str(getattr(gsplat, "__version__", "unknown"))


def card_arch(device_index: int = 0) -> str:
    """The CUDA compute capability of a card as ``TORCH_CUDA_ARCH_LIST`` spells it, e.g. ``9.0``."""
    import torch

    major, minor = torch.cuda.get_device_capability(device_index)
    return f"{major}.{minor}"


def built_module_path(arch: str | None = None) -> Path:
    """Where the built module for this torch, CUDA, gsplat and card is kept (``$GSTYLE_GSPLAT_MODULE`` if set)."""
    explicit = os.environ.get("GSTYLE_GSPLAT_MODULE")
    if explicit:
        return Path(explicit).expanduser()
    torch_version, cuda_version, gsplat_version = _versions()
    arch = arch or card_arch()
    tag = f"gsplat{gsplat_version}-torch{torch_version}-cuda{cuda_version}-sm{arch.replace('.', '')}"
    return cache_dir() / "gsplat" / tag.replace("+", "_") / f"{MODULE_NAME}.so"


def _load_built(path: Path) -> object:
    """Import a built module file and register it where gsplat looks for its compiled part first."""
    import torch  # noqa: F401  (the extension links against torch's libraries: load them first)

    loader = importlib.machinery.ExtensionFileLoader(MODULE_NAME, str(path))
    spec = importlib.util.spec_from_file_location(MODULE_NAME, str(path), loader=loader)
    if spec is None:
        raise GsplatUnavailable(f"cannot load gsplat's module from {path}")
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    sys.modules["gsplat.csrc"] = module
    return module


def _build(log: Callable[[str], None], arch: str) -> Path:
    """Compile gsplat's CUDA code for ``arch`` through its own JIT build; return the built file."""
    os.environ.setdefault("TORCH_CUDA_ARCH_LIST", arch)
    os.environ.setdefault("MAX_JOBS", str(max(1, os.cpu_count() or 1)))
    log(
        f"gsplat: building its CUDA rasterizer for this GPU (sm {arch}, {os.environ['MAX_JOBS']} jobs); this "
        "happens once and takes minutes; later runs load the built module"
    )
    started = time.perf_counter()
    try:
        from gsplat.cuda import _backend
    except Exception as error:  # the JIT build raises many kinds (subprocess, OSError, ImportError)
        raise GsplatUnavailable(f"gsplat's CUDA build failed: {error}") from error
    if _backend._C is None:
        raise GsplatUnavailable(
            "gsplat found no CUDA toolkit (nvcc) to build its rasterizer: install the CUDA toolkit matching "
            f"torch's CUDA {_versions()[1]}, or bring a built module ($GSTYLE_GSPLAT_MODULE)"
        )
    built = Path(_backend._C.__file__)
    log(f"gsplat: built in {time.perf_counter() - started:.0f} s ({built})")
    return built


def ensure_gsplat(log: Callable[[str], None] = print) -> object:
    """Make ``gsplat.rasterization`` usable on CUDA: load the kept module or build it once. Returns the module."""
    import torch

    if not torch.cuda.is_available():
        raise GsplatUnavailable("gsplat needs CUDA, and torch sees no CUDA device here")
    cached = sys.modules.get("gsplat.csrc")
    if cached is not None:
        return cached
    target = built_module_path()
    if target.is_file():
        module = _load_built(target)
    else:
        built = _build(log, card_arch())
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(".so.partial")
        shutil.copyfile(built, partial)
        partial.replace(target)
        log(f"gsplat: kept the built module at {target}")
        from gsplat.cuda import _backend

        module = _backend._C
    return module


def build_pending() -> bool:
    """Whether making gsplat usable now would build its CUDA module: torch sees CUDA, no module is loaded in this
    process and none is kept for this torch, CUDA, gsplat and card. False where gsplat cannot be used at all
    (``ensure_gsplat`` then raises the reason)."""
    import torch

    if sys.modules.get("gsplat.csrc") is not None or not torch.cuda.is_available():
        return False
    try:
        return not built_module_path().is_file()
    except GsplatUnavailable:
        return False


class RasterizerSetup:
    """A run's one-off setup of its rasterizer on ``device``, before its first render: on CUDA, gsplat's module
    loaded or built (``ensure_gsplat``); elsewhere nothing. ``note`` words it for a UI: before a build, what is
    about to take minutes (``BUILD_NOTE``); after one, how long it took; otherwise ""."""

    def __init__(self, device, log: Callable[[str], None] = print) -> None:
        self.done = getattr(device, "type", str(device)) != "cuda"
        self.log = log
        self.outcome = ""  # what ``prepare`` did, worded (a build; a quick load says nothing)

    @property
    def note(self) -> str:
        """What the next ``prepare`` will spend minutes on, or what it did; "" when there is nothing to say."""
        if self.done:
            return self.outcome
        return BUILD_NOTE if build_pending() else ""

    def prepare(self) -> float:
        """Load or build gsplat's module the first time (raises ``GsplatUnavailable`` with the reason and the way
        round it, the CPU); returns the seconds a build took (0 otherwise: nothing to do, or a module kept before
        was loaded)."""
        if self.done:
            return 0.0
        building = build_pending()
        started = time.perf_counter()
        try:
            ensure_gsplat(self.log)
        except GsplatUnavailable as error:  # the run stops here: say how to go on without the GPU's rasterizer
            raise GsplatUnavailable(f"{error}; or compute on the CPU (--device cpu)") from error
        self.done = True
        if not building:
            return 0.0
        seconds = time.perf_counter() - started
        self.outcome = f"built gsplat's rasterizer for this GPU in {seconds:.0f} s (later runs load it)"
        return seconds
