"""fp32 against bf16 (``--precision``), side by side in one run: the networks' floor, then whole preview runs.

    .venv/bin/python bench/precision.py [--precisions fp32 auto] [--scenes demo biker] [--repeats 1] [--threads N]
                                        [--floor-only] [--out-dir out/precision]

1. The floor at both precisions: VGG-16 (conv1_1 … relu3_3, the weights the product loads) forward+backward on a
   256×256 image, and one NNFM nearest-neighbour search of a 192×256 render's features against The Starry Night at
   256 px (fp32, and bf16 as ``--precision bf16`` runs it); interleaved, median of ``--floor-repeats``, in ms.
2. ``gstyle stylize SCENE --style starry_night --preset preview --precision P`` for each scene and precision, one
   after the other in alternating order (``--repeats`` rounds), each in its own process; from each OUT.json: the
   stylize phase's seconds, the whole run's, the NNFM drop and the structure figure (both measured in fp32 whatever
   the run's precision), and what ``decisions.precision`` says (``auto`` names what it picked and why); besides, the
   stylize phase's CPU seconds (all threads): with ``--threads 1`` they hardly move with other load, where wall
   seconds on a shared machine scatter by 2× (with two threads both figures suffer from a busy core).
The table gives each precision's figures (medians over the rounds) and, against fp32 in the same run, the stylize
phase's speed-up (wall and CPU seconds), the NNFM drop difference in points and the structure difference. The
machine's load (``os.getloadavg``) is printed beside every run. Last line: ``RESULT`` with them per scene (with
``--floor-only``: the floors).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gstyle_core.machine import cpu_description, set_torch_threads  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
STYLE = DATA / "styles" / "starry_night_vangogh.jpg"
SCENES = {"demo": None, "biker": DATA / "scenes" / "playcanvas" / "biker.spz"}  # None: the bundled demo


def load() -> str:
    """The 1/5/15-minute load averages."""
    return "load " + " ".join(f"{v:.1f}" for v in os.getloadavg())


def floor_ms(repeats: int) -> dict[str, dict[str, float]]:
    """Median ms of VGG forward+backward at 256² and of one NNFM search at 192×256 per precision (interleaved)."""
    import torch

    from gstyle_core.engine.objective import resize_long_side, to_bchw
    from gstyle_core.images import load_style_image
    from gstyle_core.style.features import concat_features, normalise_vectors
    from gstyle_core.style.nnfm import StyleTarget, nearest_indices
    from gstyle_core.style.vgg import load_vgg

    nets = {p: load_vgg(dtype=d, channels_last=p == "bf16")
            for p, d in (("fp32", torch.float32), ("bf16", torch.bfloat16))}
    painting = to_bchw(resize_long_side(load_style_image(STYLE), 256))
    targets = {p: StyleTarget.from_image(nets[p], painting) for p in nets}
    gen = torch.Generator().manual_seed(0)
    image = torch.rand(1, 3, 256, 256, generator=gen)
    render = torch.rand(1, 3, 192, 256, generator=gen)
    queries = {p: normalise_vectors(concat_features(nets[p](render)).permute(0, 2, 3, 1).flatten(0, 2), dim=1)
               for p in nets}

    def vgg(p: str) -> None:
        x = image.clone().requires_grad_(True)
        concat_features(nets[p](x)).square().mean().backward()

    def search(p: str) -> None:
        m = targets[p].search_matrix
        with torch.no_grad():
            nearest_indices(queries[p].to(m.dtype) @ m)

    times: dict[str, dict[str, list[float]]] = {p: {"vgg": [], "search": []} for p in nets}
    for i in range(repeats + 1):  # the first round warms up
        for p in nets:
            for part, fn in (("vgg", vgg), ("search", search)):
                t0 = time.perf_counter()
                fn(p)
                if i:
                    times[p][part].append(1000 * (time.perf_counter() - t0))
    return {p: {part: statistics.median(ts) for part, ts in parts.items()} for p, parts in times.items()}


def child(argv: list[str]) -> None:
    """``gstyle stylize argv`` as the CLI runs it, plus the CPU seconds of each phase (all the process's threads;
    ``time.process_time``) written to OUT.cpu.json: with one thread they do not grow with the machine's load."""
    from gstyle_core.cli.stylize import add_stylize_arguments, stylize_command
    from gstyle_core.engine.stylizer import Stylizer

    cpu: dict[str, float] = {}
    step = Stylizer.step

    def timed_step(self):
        t0 = time.process_time()
        rep = step(self)
        cpu[rep.phase] = cpu.get(rep.phase, 0.0) + time.process_time() - t0
        return rep

    Stylizer.step = timed_step
    parser = argparse.ArgumentParser()
    add_stylize_arguments(parser)
    args = parser.parse_args(argv)
    stylize_command(args)
    Path(args.out).with_suffix(".cpu.json").write_text(json.dumps(cpu))


def stylize(scene: str, precision: str, out_dir: Path, threads: int | None, tag: str) -> dict:
    """One ``gstyle stylize`` run in its own process (``--threads``: torch's, numba's and OpenMP's); the figures of its
    OUT.json and the stylize phase's CPU seconds."""
    out = out_dir / f"{scene}_{precision}_{tag}.ply"
    cmd = [sys.executable, __file__, "--child", "--style", str(STYLE), "--preset", "preview", "--precision", precision,
           "--out", str(out), "--force"]
    if SCENES[scene] is not None:
        cmd.insert(3, str(SCENES[scene]))
    env = dict(os.environ)
    if threads:
        cmd += ["--threads", str(threads)]
        env.update({k: str(threads) for k in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS")})
    before = load()
    subprocess.run(cmd, check=True, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    summary = json.loads(out.with_suffix(".json").read_text())
    q = summary["quality"]
    return {"stylize_s": summary["seconds_per_phase"]["stylize"], "total_s": summary["seconds_total"],
            "stylize_cpu": json.loads(out.with_suffix(".cpu.json").read_text())["stylize"],
            "drop": 100 * q["nnfm_drop"], "structure": q["structure"], "load": f"{before} → {load()}",
            "decision": summary["decisions"].get("precision", "?")}


def print_floor(floor: dict[str, dict[str, float]]) -> None:
    print(f"{'floor (median ms)':<44} {'fp32':>8} {'bf16':>8} {'fp32/bf16':>10}")
    for part, label in (("vgg", "VGG-16 forward+backward, 256×256"),
                        ("search", "NNFM search, 192×256 vs painting at 256 px")):
        a, b = floor["fp32"][part], floor["bf16"][part]
        print(f"{label:<44} {a:>8.1f} {b:>8.1f} {a / b:>10.2f}")


def main() -> None:
    if sys.argv[1:2] == ["--child"]:
        child(sys.argv[2:])
        return
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--precisions", nargs="+", default=["fp32", "auto"], choices=["fp32", "bf16", "auto"])
    p.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    p.add_argument("--repeats", type=int, default=1, help="rounds of runs (the order alternates between rounds)")
    p.add_argument("--floor-repeats", type=int, default=7)
    p.add_argument("--floor-only", action="store_true", help="only the floor table")
    p.add_argument("--threads", type=int, default=None, help="torch threads of the runs (default: torch's)")
    p.add_argument("--out-dir", default=str(ROOT / "out" / "precision"))
    args = p.parse_args()
    import torch

    if args.threads:
        set_torch_threads(args.threads)
    print(f"cpu: {cpu_description()}; torch {torch.__version__}, {torch.get_num_threads()} threads; {load()}")
    floor = floor_ms(args.floor_repeats)
    print_floor(floor)
    if args.floor_only:
        print("RESULT " + " ".join(f"floor_{part}_{p}_ms={floor[p][part]:.1f}"
                                   for part in ("vgg", "search") for p in ("fp32", "bf16")))
        return
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    runs: dict[tuple[str, str], list[dict]] = {}
    for r in range(args.repeats):
        for scene in args.scenes:
            order = args.precisions if r % 2 == 0 else list(reversed(args.precisions))
            for precision in order:
                res = stylize(scene, precision, out_dir, args.threads, f"r{r}")
                runs.setdefault((scene, precision), []).append(res)
                print(f"  {scene} {precision}: stylize {res['stylize_s']:.1f} s ({res['stylize_cpu']:.1f} CPU s), "
                      f"total {res['total_s']:.0f} s, "
                      f"drop {res['drop']:.2f} %, structure {res['structure']:.3f} ({res['load']}); "
                      f"{res['decision']}", flush=True)
    print_runs(runs, args.scenes, args.precisions)


def print_runs(runs: dict[tuple[str, str], list[dict]], scenes: list[str], precisions: list[str]) -> None:
    """The table (medians over rounds) with the ratios to fp32, and the RESULT line."""
    def med(scene: str, precision: str, key: str) -> float:
        return statistics.median(r[key] for r in runs[(scene, precision)])

    print(f"{'scene':<7} {'precision':<16} {'stylize s':>9} {'CPU s':>7} {'total s':>8} {'NNFM drop':>9} "
          f"{'structure':>9} {'speed-up':>8} {'CPU s-up':>8} {'Δ drop':>7} {'Δ struct':>8}")
    result = []
    for scene in scenes:
        for precision in precisions:
            picked = runs[(scene, precision)][0]["decision"].split(" ")[0].split(":")[0]
            name = precision if precision != "auto" else f"auto → {picked}"
            s, c, d, st = (med(scene, precision, k) for k in ("stylize_s", "stylize_cpu", "drop", "structure"))
            cells = ""
            if precision != "fp32" and "fp32" in precisions:
                speed, cpu_speed = med(scene, "fp32", "stylize_s") / s, med(scene, "fp32", "stylize_cpu") / c
                dd, ds = d - med(scene, "fp32", "drop"), st - med(scene, "fp32", "structure")
                cells = f"{speed:>8.2f} {cpu_speed:>8.2f} {dd:>+7.2f} {ds:>+8.3f}"
                key = f"{scene}_{precision}"
                result.append(f"{key}_speedup={speed:.2f} {key}_cpu_speedup={cpu_speed:.2f} "
                              f"{key}_drop_diff={dd:+.2f} {key}_structure_diff={ds:+.3f}")
            print(f"{scene:<7} {name:<16} {s:>9.1f} {c:>7.1f} {med(scene, precision, 'total_s'):>8.0f} {d:>9.2f} "
                  f"{st:>9.3f} {cells}")
    print("RESULT " + " ".join(result))


if __name__ == "__main__":
    main()
