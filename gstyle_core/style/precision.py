"""Which precision the style networks run in (``--precision auto|fp32|bf16``), and why (``decisions.precision``).

bf16 covers VGG-16 (its convolutions in bfloat16, channels_last, forward and backward) and the NNFM
nearest-neighbour search (``nnfm.nnfm_loss``: the search runs in the precision of the network its style target was
taken with), the broad-strokes term's levels included (they run on the same network). The scene's colours, the
coherent-strokes field, the content targets, the loss values, the NNFM distances and the optimisers stay float32.
On a CPU with native bf16 dot products (AVX512-BF16, AMX) bf16 is about twice as fast; without them it is emulated
and several times slower. ``auto`` decides, in this order:

1. ``$GSTYLE_PRECISION`` (``fp32`` or ``bf16``) when set; the test suite sets fp32, so no result of it depends on
   the CPU it runs on;
1b. on a CUDA run (``cuda_card``): bf16 where the card computes it natively, else fp32, without timing;
2. the choice remembered for this CPU model and torch version in ``<cache folder>/precision.json``;
3. fp32 without timing on an x86 CPU whose flags say it has no native bf16;
4. otherwise both are timed at the working size (VGG forward+backward and one NNFM search: a warm-up, then the best
   of ``TIMED_ROUNDS`` interleaved runs each, one when the first is lopsided; about a second in all), bf16 is picked
   only when it takes at most ``BF16_MARGIN`` of fp32's time, and the choice is remembered.

A corrupt cache file is ignored and rewritten (atomically); an unwritable cache folder only costs a timing next
time. Torch-free at import (the studio reads ``PRECISIONS`` at start).
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable, Mapping
from datetime import date
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..machine import CpuInfo, cpu_info
from ..paths import cache_dir as default_cache_dir

if TYPE_CHECKING:
    import torch

PRECISIONS = ("auto", "fp32", "bf16")
PRECISION_ENV = "GSTYLE_PRECISION"
CACHE_FILE = "precision.json"
CACHE_FORMAT = "gstyle-precision/1"
BF16_MARGIN = 0.9  # bf16 must take at most this fraction of fp32's time (it rounds: a tie is not worth it)
TIMED_ROUNDS = 2
DECISIVE = 1.5  # a first round this lopsided decides without a second one
NATIVE_BF16_FLAGS = ("avx512_bf16", "amx_bf16")
COVERS = ("VGG-16 (channels_last) and the NNFM searches (block 3 and the broad-strokes term's levels) in bf16; "
          "colours, the coherent-strokes field, content targets and the optimisers in fp32")

Timer = Callable[[str, tuple[int, int]], float]  # (precision, (height, width)) -> seconds of one timed run


def torch_dtype(precision: str) -> torch.dtype:
    """``torch.bfloat16`` for ``"bf16"``, ``torch.float32`` for ``"fp32"``."""
    import torch

    if precision not in ("fp32", "bf16"):
        raise ValueError(f"precision must be fp32 or bf16 here, got {precision!r}")
    return torch.bfloat16 if precision == "bf16" else torch.float32


def working_size(width: int) -> tuple[int, int]:
    """(height, width) that ``auto`` times at: a 4:3 frame of the working width."""
    width = max(16, int(width))
    return max(16, round(width * 3 / 4)), width


def machine_key(cpu: CpuInfo) -> str:
    """What a remembered choice is valid for: the CPU model and the torch version."""
    import torch

    return f"{cpu.model} | torch {torch.__version__}"


def native_bf16(cpu: CpuInfo, arch: str | None = None) -> bool | None:
    """True: the CPU has native bf16 dot products; False: an x86 CPU whose flags lack them; None: not known."""
    if cpu.flags is None:
        return None
    if any(flag in cpu.flags for flag in NATIVE_BF16_FLAGS):
        return True
    arch = (arch or platform.machine()).lower()
    return False if arch in ("x86_64", "amd64", "i686", "x86") else None


def read_choices(path: Path) -> dict[str, dict[str, Any]]:
    """The remembered choices by machine key; {} for a missing, unreadable or corrupt file."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict) or data.get("format") != CACHE_FORMAT or not isinstance(data.get("choices"), dict):
        return {}
    return {k: v for k, v in data["choices"].items() if _valid_entry(v)}


def _valid_entry(entry: Any) -> bool:
    return (isinstance(entry, dict) and entry.get("precision") in ("fp32", "bf16")
            and all(isinstance(entry.get(k), (int, float)) and entry[k] > 0 for k in ("fp32_s", "bf16_s")))


def remember(path: Path, key: str, entry: dict[str, Any]) -> bool:
    """Add ``entry`` under ``key`` to the cache file (other machines' entries kept, a corrupt file replaced),
    atomically; False when it cannot be written."""
    from ..atomic import atomic_write_text

    choices = read_choices(path)
    choices[key] = entry
    try:
        atomic_write_text(path, json.dumps({"format": CACHE_FORMAT, "choices": choices}, indent=2) + "\n")
    except OSError:
        return False
    return True


class ProbeTimer:
    """The real timer: one VGG-16 forward+backward (to relu3_3) and one NNFM search at a precision, on random
    inputs; the networks (random weights: the time does not depend on them) are built once per precision. It
    draws from its own random generator: the run's random state is untouched."""

    def __init__(self) -> None:
        self._nets: dict[str, Any] = {}
        self._matrices: dict[tuple[int, int], Any] = {}

    def __call__(self, precision: str, size: tuple[int, int]) -> float:
        import torch

        from .features import normalise_vectors
        from .nnfm import nearest_indices
        from .vgg import VGGFeatures

        dtype = torch_dtype(precision)
        gen = torch.Generator().manual_seed(0)
        if precision not in self._nets:
            with torch.random.fork_rng(devices=[]):
                self._nets[precision] = VGGFeatures(dtype=dtype, channels_last=dtype == torch.bfloat16)
        if size not in self._matrices:  # a painting's candidates at the working size
            count = max(1, (size[0] // 4) * (size[1] // 4))
            self._matrices[size] = normalise_vectors(torch.randn(768, count, generator=gen), dim=0)
        image = torch.rand(1, 3, *size, generator=gen).requires_grad_(True)
        start = time.perf_counter()
        feats = self._nets[precision].stacked(image)  # as the loss runs it
        feats.square().mean().backward()
        with torch.no_grad():
            vectors = feats.detach().permute(0, 2, 3, 1).flatten(0, 2).to(dtype)
            nearest_indices(vectors @ self._matrices[size].to(dtype))
        return time.perf_counter() - start


def measure(timer: Timer, size: tuple[int, int], rounds: int = TIMED_ROUNDS) -> dict[str, float]:
    """Best time of each precision over ``rounds`` interleaved runs, after one warm-up run each; the first round
    alone when one precision took under ``1 / DECISIVE`` of the other's time (no second look can change that)."""
    for precision in ("fp32", "bf16"):
        timer(precision, size)
    best = {"fp32": float("inf"), "bf16": float("inf")}
    for _ in range(rounds):
        for precision in best:
            best[precision] = min(best[precision], float(timer(precision, size)))
        if max(best.values()) >= DECISIVE * min(best.values()):
            break
    return best


def _timing_words(entry: Mapping[str, Any]) -> str:
    h, w = entry.get("size", ("?", "?"))
    fp32, bf16 = entry["fp32_s"], entry["bf16_s"]
    return (f"at {w}×{h}, VGG-16 forward+backward and one NNFM search took {1000 * bf16:.0f} ms in bf16, "
            f"{1000 * fp32:.0f} ms in fp32: fp32/bf16 = {fp32 / bf16:.2f} (bf16 is picked at ≥ {1 / BF16_MARGIN:.2f})")


def choose_precision(requested: str, size: tuple[int, int], cache_dir: str | Path | None = None,
                     timer: Timer | None = None, cpu: CpuInfo | None = None,
                     env: Mapping[str, str] | None = None, gpu: tuple[str, bool] | None = None) -> tuple[str, str]:
    """(``"fp32"`` or ``"bf16"``, the reason in words) for ``requested`` (one of ``PRECISIONS``) at the working
    ``size`` (height, width); see the module docstring for how ``auto`` decides. ``gpu``: a CUDA run's card
    (``cuda_card``): after ``$GSTYLE_PRECISION``, ``auto`` takes bf16 where the card computes it natively, else fp32,
    without timing. ``timer``, ``cpu`` and ``env`` replace the real timing, this machine's CPU and ``os.environ``
    (tests)."""
    if requested not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {requested!r}")
    if requested != "auto":
        extra = f"; {COVERS}" if requested == "bf16" else ""
        return requested, f"{requested}: asked for (--precision {requested}){extra}"
    forced = (os.environ if env is None else env).get(PRECISION_ENV, "").strip().lower()
    if forced in ("fp32", "bf16"):
        return forced, f"{forced} (auto): set by ${PRECISION_ENV}"
    ignored = f" (${PRECISION_ENV}={forced!r} ignored: not fp32 or bf16)" if forced else ""
    if gpu is not None:
        card, native = gpu
        if native:
            return "bf16", f"bf16 (auto): {card} computes bf16 natively; {COVERS}{ignored}"
        return "fp32", f"fp32 (auto): {card} has no native bf16{ignored}"
    cpu = cpu or cpu_info()
    key = machine_key(cpu)
    path = Path(cache_dir if cache_dir is not None else default_cache_dir()) / CACHE_FILE
    entry = read_choices(path).get(key)
    if entry is not None:
        return entry["precision"], (f"{entry['precision']} (auto): remembered for {key} in {path} (measured "
                                    f"{entry.get('measured', '?')}: {_timing_words(entry)}){ignored}")
    if native_bf16(cpu) is False:
        return "fp32", (f"fp32 (auto): {cpu.model} has no native bf16 ({' / '.join(NATIVE_BF16_FLAGS)}): bf16 would "
                        f"be emulated and slower, not timed{ignored}")
    times = measure(timer or ProbeTimer(), size)
    choice = "bf16" if times["bf16"] <= BF16_MARGIN * times["fp32"] else "fp32"
    entry = {"precision": choice, "fp32_s": round(times["fp32"], 5), "bf16_s": round(times["bf16"], 5),
             "size": [int(size[0]), int(size[1])], "measured": date.today().isoformat(), "cpu": cpu.describe()}
    kept = f"remembered in {path}" if remember(path, key, entry) else f"not remembered ({path} cannot be written)"
    return choice, f"{choice} (auto): measured now on {key}: {_timing_words(entry)}; {kept}{ignored}"


def resolve_precision(settings: Any, vgg: Any = None, **choose: Any) -> tuple[str, str]:
    """The run's precision and its reason from ``settings.precision`` at its working width; a network given by
    the caller (``vgg``) keeps the precision it is in. ``choose``: passed on to :func:`choose_precision`."""
    if vgg is not None:
        import torch

        precision = "bf16" if getattr(vgg, "compute_dtype", torch.float32) == torch.bfloat16 else "fp32"
        return precision, f"{precision}: the caller's VGG network runs in {precision}"
    return choose_precision(getattr(settings, "precision", "fp32"), working_size(settings.working_width),
                            gpu=cuda_card(settings), **choose)


def cuda_card(settings: Any) -> tuple[str, bool] | None:
    """(the card's name, whether it computes bf16 natively: compute capability 8.0 and up, as
    ``torch.cuda.is_bf16_supported``) for a run on CUDA (``settings.device`` auto or cuda, and torch sees one); None
    for a run elsewhere (the CPU's rules apply)."""
    if getattr(settings, "device", "cpu") not in ("auto", "cuda"):
        return None
    import torch

    if not torch.cuda.is_available():
        return None
    return torch.cuda.get_device_name(0), bool(torch.cuda.is_bf16_supported(including_emulation=False))
