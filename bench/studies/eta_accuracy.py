"""How right the studio's ETA is (issue #65 item 3): the real engine stepped on a scene (the bundled demo by default,
preset preview), and at each step the ETA the panel would show, computed by the studio's own ``EngineSync._eta``
from the worker's state (the run's plan, its step times, the session's ``MachineRates``), against the real end.

Prints the run's phases as they came (steps, seconds a step, Gaussians), the ETA's error (ETA / real time left - 1)
at 20 %, 40 %, 60 % and 80 % of the run's time and of its steps, and its swing (the largest and smallest ETA +
elapsed, the end it promises) over the run's first fifth and after.

Usage: .venv/bin/python bench/studies/eta_accuracy.py [--scene PATH] [--preset preview]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from app.engine_factory import make_stylizer  # noqa: E402
from app.engine_host import report_to_dict  # noqa: E402
from app.studio_sync import EngineSync  # noqa: E402
from app.worker import WorkerState  # noqa: E402
from gstyle_core.assets import DEMO_SCENE  # noqa: E402
from gstyle_core.engine.plan import MachineRates  # noqa: E402
from gstyle_core.machine import cpu_description  # noqa: E402


def run(scene: str, preset: str) -> list[tuple[str, float, float | None, int]]:
    """(phase, elapsed s at the step's end, the ETA the panel shows then, Gaussians) of every step of a run."""
    engine = make_stylizer(scene=scene, preset=preset)
    rates = MachineRates()
    st = WorkerState(alive=True, ready=True)
    st.plans = {"run": engine.run_plan(), "working_width": int(engine.settings.working_width)}
    panel = SimpleNamespace(step=0, total_steps=0)
    sync = SimpleNamespace(engine=SimpleNamespace(bridge=SimpleNamespace(rates=rates)), panel=panel)
    out: list[tuple[str, float, float | None, int]] = []
    t0 = time.perf_counter()
    done = False
    while not done:
        rep = report_to_dict(engine.step())
        st.reports_received += 1
        st.step_times.add(rep)
        rates.add(rep)
        st.step_seconds += float(rep.get("seconds") or 0.0)
        panel.step, panel.total_steps = int(rep.get("step", 0)), int(rep.get("total_steps", 0))
        done = bool(rep.get("done"))
        out.append((str(rep.get("phase")), time.perf_counter() - t0, None if done else EngineSync._eta(sync, st),
                    int(rep.get("gaussians") or 0)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default=str(DEMO_SCENE))
    ap.add_argument("--preset", default="preview")
    ap.add_argument("--csv", help="also write every step's phase, seconds and ETA here")
    args = ap.parse_args()
    steps = run(args.scene, args.preset)
    if args.csv:
        Path(args.csv).write_text("phase,elapsed_s,eta_s,gaussians\n" + "".join(
            f"{p},{at:.3f},{eta},{n}\n" for p, at, eta, n in steps))
    print(f"{Path(args.scene).name}, {args.preset}: {len(steps)} steps, {steps[-1][1]:.1f} s; {cpu_description()}")
    print_phases(steps)
    print_errors([(at, eta) for _p, at, eta, _n in steps])


def print_phases(steps: list[tuple[str, float, float | None, int]]) -> None:
    """Each stretch of steps of one phase: its steps, seconds a step (mean) and Gaussians at its end."""
    print("| phase | steps | s a step | Gaussians |\n|---|---|---|---|")
    start, before = 0, 0.0
    for i, (phase, at, _eta, count) in enumerate(steps):
        if i + 1 == len(steps) or steps[i + 1][0] != phase:
            n = i + 1 - start
            print(f"| {phase} | {start + 1}-{i + 1} | {(at - before) / n:.3f} | {count:,} |")
            start, before = i + 1, at


def print_errors(steps: list[tuple[float, float | None]]) -> None:
    """The ETA's error at fractions of the run's time and of its steps, and the ends it promised."""
    end = steps[-1][0]
    print("| at | step | real left s | ETA s | error |\n|---|---|---|---|---|")
    for label, index in [(f"{share:.0%} of the time", next(i for i, (at, _e) in enumerate(steps) if at >= share * end))
                         for share in (0.2, 0.4, 0.6, 0.8)] + \
                        [(f"{share:.0%} of the steps", max(0, int(round(share * len(steps))) - 1))
                         for share in (0.2, 0.4, 0.6, 0.8)]:
        at, eta = steps[index]
        left = end - at
        error = f"{eta / left - 1:+.0%}" if eta is not None and left > 0 else "-"
        print(f"| {label} | {index + 1} | {left:.1f} | {'-' if eta is None else f'{eta:.1f}'} | {error} |")
    for name, part in (("first fifth", [s for s in steps if s[0] < end / 5]),
                       ("after", [s for s in steps if s[0] >= end / 5])):
        ends = [at + eta for at, eta in part if eta is not None]
        if ends:
            print(f"promised end over the {name} of the time: {min(ends):.1f} .. {max(ends):.1f} s (real {end:.1f} s)")

if __name__ == "__main__":
    main()
