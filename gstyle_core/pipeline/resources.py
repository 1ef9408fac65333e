"""Bounded resources: the default cap on the Gaussian count, derived from the memory available at start.

The estimate is the peak resident-memory growth per extra Gaussian of a stylization run (geometry and c_gt with
their gradients and Adam moments in a refit, c_s with its Adam moments, the per-view colour caches of the
rasterizer). ``bench/bench_memory_per_gaussian.py`` measured it as the slope of peak RSS (``ru_maxrss``) over
the Gaussian count, in fresh processes that stylize the demo scene replicated 1x and 3-4x (16 views) through ground
truth, a pre-processing refit, one stylization epoch and a colour-gradient split with its refit:
1,646 bytes per Gaussian at 48 px working width, 1,588 at 192 px and 4,229 at 512 px. A fixed part (parameters,
gradients, Adam moments, one cache record per Gaussian and view) dominates at small widths; the rest grows with
the pixels a Gaussian covers, i.e. with the square of the width. The model ``BASE_BYTES + PER_WIDTH_SQUARED · w²``
(1,700 + 0.012 · w²: 1,728 / 2,143 / 4,846 bytes at 48 / 192 / 512 px) lies above all three measurements; above
512 px it is an extrapolation.

On CUDA the card's memory bounds the count too: ``bench/bench_memory_per_gaussian.py --device cuda`` measured the peak
of torch's reserved GPU memory growing by 825 bytes a Gaussian at 512 px (716 allocated; the demo ×1 and ×4, an
NVIDIA H100: docs/gpu.md). Only that width was measured: other widths take the host model's shape scaled to it (an
extrapolation). The cap is the lower of the host's and the card's.
"""

from __future__ import annotations

import math
import os

BASE_BYTES = 1_700  # per Gaussian, at any width (module docstring)
PER_WIDTH_SQUARED = 0.012  # per Gaussian and squared pixel of working width
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
