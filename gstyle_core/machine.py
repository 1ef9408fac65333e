"""Where a run happened: the CPU's model, its usable cores and the instruction-set flags that decide its speed.

Torch-free (benches print it before importing anything heavy). Linux reads ``/proc/cpuinfo``; without it (other
systems, restricted containers) the model comes from :mod:`platform` and the flags are reported as unknown.
"""

from __future__ import annotations

import os
import platform
from dataclasses import dataclass
from pathlib import Path

CPUINFO = Path("/proc/cpuinfo")
# The flags that change which kernels torch and oneDNN pick: 256-bit and 512-bit vectors, native bfloat16 dot
# products (AVX512-BF16) and AMX tiles (bf16 matrix units).
FLAGS_THAT_MATTER = ("avx2", "avx512f", "avx512_bf16", "amx_bf16", "amx_tile")


@dataclass(frozen=True)
class CpuInfo:
    """The CPU's model name, usable cores and which of ``FLAGS_THAT_MATTER`` it has (None: not known)."""

    model: str
    cores: int
    flags: tuple[str, ...] | None

    def describe(self) -> str:
        """One line, e.g. ``AMD EPYC, 2 cores, avx2 avx512f avx512_bf16 (no amx_bf16 amx_tile)``."""
        if self.flags is None:
            flags = "flags unknown"
        else:
            missing = [f for f in FLAGS_THAT_MATTER if f not in self.flags]
            flags = " ".join(self.flags) or "none of " + " ".join(FLAGS_THAT_MATTER)
            if missing and self.flags:
                flags += f" (no {' '.join(missing)})"
        return f"{self.model}, {self.cores} core{'s' if self.cores != 1 else ''}, {flags}"


def parse_cpuinfo(text: str) -> tuple[str | None, set[str] | None]:
    """The model name and the flag set of the first processor in ``/proc/cpuinfo`` text (None where absent)."""
    model: str | None = None
    flags: set[str] | None = None
    for line in text.splitlines():
        key, sep, value = line.partition(":")
        if not sep:
            continue
        key = key.strip().lower()
        if key == "model name" and model is None:
            model = value.strip() or None
        elif key in ("flags", "features") and flags is None:  # x86 says "flags", ARM "Features"
            flags = set(value.split())
        if model is not None and flags is not None:
            break
    return model, flags


def usable_cores() -> int:
    """The cores this process may run on (its affinity mask where the OS has one; else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def cpu_info(cpuinfo: Path | str = CPUINFO) -> CpuInfo:
    """What this machine's CPU is; never raises for a missing or unreadable ``cpuinfo`` file."""
    try:
        text = Path(cpuinfo).read_text(errors="replace")
    except OSError:
        text = ""
    model, flags = parse_cpuinfo(text)
    if model is None:
        model = platform.processor() or platform.machine() or "unknown CPU"
    present = None if flags is None else tuple(f for f in FLAGS_THAT_MATTER if f in flags)
    return CpuInfo(model, usable_cores(), present)


def cpu_description(cpuinfo: Path | str = CPUINFO) -> str:
    """``cpu_info(cpuinfo).describe()``: the line benches print at the top of their output."""
    return cpu_info(cpuinfo).describe()


def set_torch_threads(count: int) -> None:
    """Set torch's intra-op threads so that the count holds for the whole run. numba's parallel pool is launched first:
    its launch sets the OpenMP thread count of the calling thread, which torch reads, so a pool launched later (the
    first render of a process) silently changed ``--threads 1`` to numba's count (measured: a resumed run's first
    step turned torch's 1 thread into 2, and its sums over more than 32,768 values then came out differently)."""
    import numba
    import torch

    numba.get_num_threads()  # launches numba's threading layer now, not in the middle of a run
    torch.set_num_threads(count)


if __name__ == "__main__":
    print(cpu_description())


def peak_rss_bytes(pid: int | str = "self") -> int:
    """Peak resident memory (``VmHWM``, bytes) of a process, from Linux's /proc; 0 where it cannot be read."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0
