"""Which torch device a run computes on (``--device auto|cpu|cuda|mps``), and why (``decisions.device``).

- ``auto``: CUDA when torch sees a CUDA device, else the CPU. Apple's MPS is used only when asked for: it has not
  been measured against the CPU here (no Mac), so ``auto`` does not pick it.
- ``cuda`` / ``mps`` asked for where torch does not see one: a clear error, never a silent fall-back.

What runs where (``docs/notes/gpu.md``): on CUDA the rasterizer is gsplat's (``raster/gsplat_backend.py``) and the style
networks, their NNFM searches and the losses run on the GPU. On MPS the networks run on the GPU and the rasterizer
stays the CPU's numba one (gsplat has no Metal backend). The scene's tensors, the optimisers' state and the
bookkeeping stay on the CPU in every case; a step moves the colours (N × 3 floats) to the device and their
gradients back.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .errors import GStyleError

if TYPE_CHECKING:
    import torch

DEVICES = ("auto", "cpu", "cuda", "mps")


class DeviceFailure(GStyleError, RuntimeError):
    """A GPU could not do its part of a run (not there, out of memory, its rasterizer not built): computing on the CPU
    avoids it (the studio offers "Continue on the CPU"; ``is_device_failure``)."""


class DeviceUnavailable(DeviceFailure):
    """The device asked for is not there (no CUDA/MPS build of torch, or no such GPU); shown as one line."""


@dataclass(frozen=True)
class DeviceChoice:
    """The resolved device, its name in words (the card) and the reason it was chosen."""

    device: torch.device
    name: str
    reason: str

    @property
    def kind(self) -> str:
        """``cpu``, ``cuda`` or ``mps``."""
        return self.device.type

    @property
    def raster_device(self) -> torch.device:
        """Where renders run: the GPU on CUDA (gsplat's kernels), else the CPU (numba; gsplat has no Metal
        backend, so an MPS run renders on the CPU)."""
        import torch

        return self.device if self.kind == "cuda" else torch.device("cpu")


def _mps_available() -> bool:
    import torch

    backend = getattr(torch.backends, "mps", None)
    return bool(backend is not None and backend.is_available())


def _cuda_name() -> str:
    import torch

    props = torch.cuda.get_device_properties(0)
    return f"{props.name} ({props.total_memory / 2**30:.0f} GiB, CUDA {torch.version.cuda})"


def resolve_device(requested: str = "auto") -> DeviceChoice:
    """The device for ``requested`` (one of ``DEVICES``), or :class:`DeviceUnavailable` saying why not."""
    import torch

    if requested not in DEVICES:
        raise ValueError(f"device must be one of {', '.join(DEVICES)}, got {requested!r}")
    cuda = torch.cuda.is_available()
    if requested == "cuda" or (requested == "auto" and cuda):
        if not cuda:
            build = "a CPU-only build" if torch.version.cuda is None else f"built for CUDA {torch.version.cuda}"
            raise DeviceUnavailable(
                f"--device cuda: torch {torch.__version__} ({build}) sees no CUDA device; on a machine with an "
                "NVIDIA GPU scripts/setup.sh installs torch's CUDA build (docs/gpu.md), or run with --device cpu"
            )
        why = "asked for (--device cuda)" if requested == "cuda" else "auto: torch sees a CUDA device"
        return DeviceChoice(torch.device("cuda", 0), _cuda_name(), why)
    if requested == "mps":
        if not _mps_available():
            raise DeviceUnavailable("--device mps: torch sees no Apple GPU (MPS) here; run with --device cpu")
        return DeviceChoice(torch.device("mps"), "Apple GPU (MPS)",
                            "asked for (--device mps): the style networks on the GPU, the rasterizer on the CPU")
    why = "asked for (--device cpu)" if requested == "cpu" else "auto: torch sees no CUDA device"
    return DeviceChoice(torch.device("cpu"), "CPU", why)


def available_devices() -> tuple[str, ...]:
    """The devices a run can compute on here: the CPU, CUDA where torch sees a CUDA device, MPS where it sees an
    Apple GPU (what a UI offers to move a run to)."""
    import torch

    return ("cpu",) + (("cuda",) if torch.cuda.is_available() else ()) + (("mps",) if _mps_available() else ())


def describe(choice: DeviceChoice) -> str:
    """One line for OUT.json's ``decisions.device`` and the logs."""
    return f"{choice.kind} ({choice.name}): {choice.reason}"


class DeviceMemoryError(DeviceFailure):
    """A GPU ran out of memory in a step; shown as one line that says what to lower (``out_of_memory``)."""


STYLIZE_LIGHTER = ("take a lighter preset, a smaller working width or a lower cap on Gaussians (--working-width, "
                   "--max-gaussians)")


def out_of_memory(choice: DeviceChoice, doing: str, lighter: str = STYLIZE_LIGHTER) -> DeviceMemoryError:
    """The error for an out-of-memory ``torch.OutOfMemoryError`` raised on ``choice``'s device while ``doing``
    (e.g. "stylize with 3,210,455 Gaussians at 512 px"): the card, what it holds, and what to lower (``lighter``),
    or the CPU. The allocator's cached blocks are released first, so the card is free for a restart."""
    import torch

    held = ""
    if choice.kind == "cuda":
        try:
            torch.cuda.empty_cache()
            free, total = torch.cuda.mem_get_info(choice.device)
            held = f"; {free / 2**30:.1f} of {total / 2**30:.1f} GiB free now"
        except RuntimeError:  # the card cannot even be asked: the line goes without it
            pass
    elif choice.kind == "mps":
        torch.mps.empty_cache()
    return DeviceMemoryError(
        f"{choice.name} ran out of memory in {doing}{held}: {lighter}, or compute on the CPU (--device cpu)")


def is_device_failure(error: BaseException) -> bool:
    """Whether ``error``, or an error it was raised from, is a GPU's failure that computing on the CPU avoids: a
    ``DeviceFailure``, or torch's out-of-memory or accelerator error (a kernel that faulted, a device lost)."""
    import torch

    kinds = (DeviceFailure, torch.OutOfMemoryError) + ((torch.AcceleratorError,)
                                                       if hasattr(torch, "AcceleratorError") else ())
    seen: set[int] = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, kinds):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return False
