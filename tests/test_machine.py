"""gstyle_core.machine: the CPU line benches print, from fake /proc/cpuinfo texts and without one."""

from __future__ import annotations

import platform
import subprocess
import sys
from pathlib import Path

from gstyle_core import machine
from gstyle_core.machine import CpuInfo, cpu_description, cpu_info, parse_cpuinfo

ROOT = Path(__file__).resolve().parents[1]

# Two processors of an AVX-512 + AMX CPU; the second block differs so that reading past the first would show.
SAPPHIRE = """processor\t: 0
vendor_id\t: GenuineIntel
model name\t: Intel(R) Xeon(R) Platinum 8480+
flags\t\t: fpu sse2 avx avx2 fma avx512f avx512bw avx512_bf16 amx_bf16 amx_tile amx_int8

processor\t: 1
model name\t: Other CPU
flags\t\t: fpu sse2
"""
HASWELL = "processor : 0\nmodel name : Intel(R) Core(TM) i7-4770 CPU @ 3.40GHz\nflags : fpu sse4_2 avx avx2 fma\n"
ARM = "processor\t: 0\nBogoMIPS\t: 50.00\nFeatures\t: fp asimd sve\nCPU implementer\t: 0x41\n"


def test_parse_reads_the_first_processor_only():
    model, flags = parse_cpuinfo(SAPPHIRE)
    assert model == "Intel(R) Xeon(R) Platinum 8480+"
    assert {"avx512_bf16", "amx_tile"} <= flags and "Other" not in model
    assert parse_cpuinfo("") == (None, None)
    assert parse_cpuinfo(ARM) == (None, {"fp", "asimd", "sve"})  # ARM: "Features", no model name


def test_description_names_model_cores_and_the_flags_that_matter(tmp_path, monkeypatch):
    monkeypatch.setattr(machine, "usable_cores", lambda: 4)
    fake = tmp_path / "cpuinfo"
    fake.write_text(SAPPHIRE)
    assert cpu_info(fake) == CpuInfo("Intel(R) Xeon(R) Platinum 8480+", 4,
                                     ("avx2", "avx512f", "avx512_bf16", "amx_bf16", "amx_tile"))
    assert cpu_description(fake) == "Intel(R) Xeon(R) Platinum 8480+, 4 cores, avx2 avx512f avx512_bf16 amx_bf16 " \
                                    "amx_tile"
    fake.write_text(HASWELL)
    assert cpu_description(fake) == "Intel(R) Core(TM) i7-4770 CPU @ 3.40GHz, 4 cores, avx2 " \
                                    "(no avx512f avx512_bf16 amx_bf16 amx_tile)"
    fake.write_text("model name : Old CPU\nflags : fpu sse2\n")
    assert cpu_description(fake) == "Old CPU, 4 cores, none of avx2 avx512f avx512_bf16 amx_bf16 amx_tile"
    monkeypatch.setattr(machine, "usable_cores", lambda: 1)
    assert cpu_description(fake).startswith("Old CPU, 1 core, ")


def test_without_cpuinfo_the_platform_names_the_cpu(tmp_path, monkeypatch):
    monkeypatch.setattr(platform, "processor", lambda: "arm")
    info = cpu_info(tmp_path / "missing")
    assert info.model == "arm" and info.flags is None and info.cores >= 1
    assert cpu_description(tmp_path / "missing").endswith(", flags unknown")
    (tmp_path / "dir").mkdir()  # unreadable as a file: the same answer, no exception
    assert cpu_info(tmp_path / "dir").flags is None
    monkeypatch.setattr(platform, "processor", lambda: "")
    monkeypatch.setattr(platform, "machine", lambda: "")
    assert cpu_info(tmp_path / "missing").model == "unknown CPU"
    arm = tmp_path / "arm"
    arm.write_text(ARM)  # flags known, none of them x86's; no model name line
    assert cpu_description(arm).startswith("unknown CPU, ") and "none of avx2" in cpu_description(arm)


def test_usable_cores_and_the_module_entry_point():
    assert 1 <= machine.usable_cores()
    out = subprocess.run([sys.executable, "-m", "gstyle_core.machine"], cwd=ROOT, capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == cpu_description()
    assert "torch" not in subprocess.run(
        [sys.executable, "-c", "import sys, gstyle_core.machine; print(sorted(sys.modules))"],
        cwd=ROOT, capture_output=True, text=True, timeout=60).stdout  # torch-free


THREADS_AFTER_NUMBAS_LAUNCH = """
import sys
sys.path.insert(0, {root!r})
import torch  # first, as the engine does: numba then finds its OpenMP runtime loaded
import numba
from gstyle_core.machine import set_torch_threads
{set_threads}
torch.ones(100_000).sum()  # torch computes first, in parallel (its OpenMP runtime starts here), as a run does
numba.get_num_threads()  # launches numba's threading layer, as its first cached parallel kernel does mid-run
print(torch.get_num_threads())
"""


def test_the_torch_thread_count_holds_past_numbas_launch():
    # with torch.set_num_threads(1) alone, numba's OpenMP layer turned the count into its own (2 on the 2-core VM):
    # a run resumed from a checkpoint then summed its losses on 2 threads where the uninterrupted run used 1
    code = THREADS_AFTER_NUMBAS_LAUNCH.format(root=str(ROOT), set_threads="set_torch_threads(1)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    assert out.stdout.split()[-1] == "1", out.stdout + out.stderr
