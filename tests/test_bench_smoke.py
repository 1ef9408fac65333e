"""Every lasting bench runs at a tiny size (its smoke arguments in bench/README.md, with ``GSTYLE_SMOKE=1``) and ends
with a ``RESULT`` line, so none rots; the index names every script in bench/ and its folders."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"
INDEX = BENCH / "README.md"
ROW = re.compile(r"^\| \[`([\w.]+)`\]\([\w.]+\) \|.*\| `([^`]*)`[^|]*\|\s*$")
HELPERS = {"tradeoff_report.py", "densify.py", "consistency.py"}


def lasting_benches() -> dict[str, str]:
    """The index's lasting benches: script name -> its smoke arguments."""
    section = INDEX.read_text(encoding="utf-8").partition("## Lasting benches")[2].partition("\n## ")[0]
    return {m.group(1): m.group(2) for m in map(ROW.match, section.splitlines()) if m}


def test_the_index_lists_every_bench_and_study():
    text = INDEX.read_text(encoding="utf-8")
    lasting = lasting_benches()
    scripts = {p.name for p in BENCH.glob("*.py")} | {p.name for p in BENCH.glob("*.sh")}
    assert scripts - HELPERS == set(lasting), "bench/README.md's table and bench/ disagree"
    assert all(h in text for h in HELPERS)
    unnamed = [p.name for folder in ("studies", "pictures") for p in (BENCH / folder).glob("*.py")
               if p.name not in text]
    assert unnamed == []
    smoke_free = [name for name, args in lasting.items() if not args]
    assert smoke_free == [], "every lasting bench needs smoke arguments"


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(lasting_benches()))
def test_a_lasting_bench_runs_at_a_tiny_size(name, tmp_path):
    args = lasting_benches()[name]
    if name.endswith(".sh"):  # the GPU check needs a card: its syntax here
        assert args == "bash -n"
        subprocess.run(["bash", "-n", str(BENCH / name)], check=True)
        return
    env = dict(os.environ, GSTYLE_SMOKE="1")  # with the suite's GSTYLE_PRECISION=fp32
    argv = [sys.executable, str(BENCH / name), *args.replace("{tmp}", str(tmp_path)).split()]
    done = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    out = done.stdout.strip().splitlines()
    assert done.returncode == 0, f"{name} exited {done.returncode}: {(done.stdout + done.stderr)[-2000:]}"
    assert out and out[-1].startswith("RESULT "), f"{name}: last line {out[-1:]}"
    assert not re.search(r"\b(failures|failed)=[1-9]", out[-1]), f"{name}: {out[-1]}"  # soak's and paths' own checks
