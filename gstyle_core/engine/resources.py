"""Bounded resources: the default cap on the Gaussian count, derived from the memory available at start.

The estimate is the peak resident-memory growth per extra Gaussian a run holds (geometry and c_gt with their
gradients and Adam moments in a refit, c_s with its Adam moments, the per-view colour caches of the rasterizer, a
step's per-entry transients). ``tests/scale_probe.py`` measured it as the slope of peak RSS (``VmHWM``) over the most
Gaussians held, in fresh processes that stylize captures of 50k and 200k Gaussians made from the demo (generated
orbit, 16 views; ground truth, a pre-processing split with its refit, one stylization epoch and a colour-gradient
split with its refit; int32 colour caches): 1,350 bytes a Gaussian at 48 px working width, 1,159 at 256 px and
1,738 at 512 px (Intel Xeon, 2 cores, 2026-12-01). ``bench/engine_scale.py`` measured 1,226 at 256 px for whole
``preview`` runs from 150k to 1.2 M Gaussians held (docs/notes/captures.md). The model ``BASE_BYTES + PER_WIDTH_SQUARED
· w²`` (1,500 + 0.004 · w²: 1,509 / 1,762 / 2,549 bytes at 48 / 256 / 512 px) lies above all of them; above 512 px it
is an extrapolation. (The model before, 1,700 + 0.012 · w², came from int64 caches and the demo replicated in place.)

On CUDA the card's memory bounds the count too: ``bench/bench_memory_per_gaussian.py --device cuda`` measured the peak
of torch's reserved GPU memory growing by 825 bytes a Gaussian at 512 px (716 allocated; the demo ×1 and ×4, an
NVIDIA H100: docs/notes/gpu.md). Only that width was measured: other widths take the host model's shape scaled to it (an
extrapolation). The cap is the lower of the host's and the card's.
"""

from __future__ import annotations

import math
import os

BASE_BYTES = 1_500  # per Gaussian, at any width (module docstring)
PER_WIDTH_SQUARED = 0.004  # per Gaussian and squared pixel of working width
MEMORY_FRACTION = 0.5  # of the memory available at start; the rest for networks, images, the app and others
FALLBACK_MAX_GAUSSIANS = 2_000_000  # when the available memory cannot be read
GPU_BYTES_AT_512 = 825  # torch's reserved GPU memory per Gaussian at 512 px (module docstring)


def available_memory_bytes() -> int | None:
    """Memory available to new allocations: ``MemAvailable`` of /proc/meminfo, else sysconf's available pages."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def bytes_per_gaussian(working_width: int) -> int:
    """Estimated peak memory per Gaussian of a run at ``working_width`` pixels."""
    return int(math.ceil(BASE_BYTES + PER_WIDTH_SQUARED * max(int(working_width), 1) ** 2))


def gpu_bytes_per_gaussian(working_width: int) -> int:
    """Estimated peak of torch's reserved GPU memory per Gaussian of a CUDA run at ``working_width`` pixels."""
    return int(math.ceil(GPU_BYTES_AT_512 * bytes_per_gaussian(working_width) / bytes_per_gaussian(512)))


def card_free_bytes(device) -> int | None:
    """The free memory of a CUDA ``device`` as its driver counts it; None where it cannot be read."""
    import torch

    try:
        return int(torch.cuda.mem_get_info(device)[0])
    except (RuntimeError, AssertionError, ValueError):
        return None


def default_max_gaussians(working_width: int, available: int | None = None,
                          card_free: int | None = None) -> tuple[int, str]:
    """``(cap, how it was derived)``: ``MEMORY_FRACTION`` of the available memory / bytes per Gaussian; with
    ``card_free`` (a CUDA run: the card's free bytes) the lower of that and the card's own such cap."""
    avail = available_memory_bytes() if available is None else available
    if not avail or avail <= 0:
        cap, how = FALLBACK_MAX_GAUSSIANS, "available memory unknown: fixed default"
    else:
        per = bytes_per_gaussian(working_width)
        cap = max(1, int(avail * MEMORY_FRACTION // per))
        how = (f"{avail / 2**30:.1f} GiB available x {MEMORY_FRACTION:g} / ~{per:,} bytes per Gaussian "
               f"at {working_width} px")
    if card_free and card_free > 0:
        per_gpu = gpu_bytes_per_gaussian(working_width)
        card_cap = max(1, int(card_free * MEMORY_FRACTION // per_gpu))
        if card_cap < cap:
            cap, how = card_cap, (f"{card_free / 2**30:.1f} GiB free on the GPU x {MEMORY_FRACTION:g} / "
                                  f"~{per_gpu:,} GPU bytes per Gaussian at {working_width} px")
    return cap, how


def gaussian_cap(settings) -> tuple[int, str]:
    """``(cap, how it was derived)`` of a run with ``settings``: its ``max_gaussians`` when set (> 0), else
    ``default_max_gaussians`` at its working width (with the card's free memory on a CUDA run)."""
    if settings.max_gaussians > 0:
        return int(settings.max_gaussians), "the max_gaussians setting"
    from ..device import resolve_device

    device = resolve_device(settings.device).raster_device
    card = card_free_bytes(device) if device.type == "cuda" else None
    return default_max_gaussians(settings.working_width, card_free=card)
