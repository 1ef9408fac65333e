"""Time VGG-16 conv1_1…relu3_3 forward+backward (fp32 vs bf16 channels_last) and the NNFM loss on this CPU (its
search in bf16 in the bf16 mode, as ``--precision bf16`` runs it; ``bench/precision.py`` compares whole runs).

Usage: .venv/bin/python bench/bench_style_vgg.py [--sizes 256 512] [--threads 2 1] [--repeats 5] [--modes fp32 ...]
Prints a table and one RESULT line (median seconds).
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from gstyle_core.machine import cpu_description
from gstyle_core.style.features import concat_features
from gstyle_core.style.nnfm import StyleTarget, nnfm_loss
from gstyle_core.style.vgg import load_vgg

MODES = {"fp32": (torch.float32, False), "fp32_cl": (torch.float32, True), "bf16_cl": (torch.bfloat16, True)}


def _time(fn, repeats: int) -> float:
    fn()  # warm-up
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    parser.add_argument("--threads", type=int, nargs="+", default=[2, 1])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--modes", nargs="+", default=["fp32", "fp32_cl", "bf16_cl"], choices=sorted(MODES),
                        help="bf16 is only fast on CPUs with AVX512-BF16/AMX; on AVX2-only CPUs it is emulated")
    args = parser.parse_args()

    vgg = load_vgg()
    style = StyleTarget.from_image(vgg, torch.rand(1, 3, 256, 256))
    results = {}
    print(f"cpu: {cpu_description()}")
    print(f"weights: {vgg.weights_source} ({vgg.convention})")
    print(f"{'threads':>7} {'size':>5} {'mode':>6} {'fwd+bwd s':>10} {'+nnfm s':>8}")
    for threads in args.threads:
        torch.set_num_threads(threads)
        for size in args.sizes:
            img = torch.rand(1, 3, size, size)
            for mode in args.modes:
                dtype, channels_last = MODES[mode]
                vgg.set_compute_mode(dtype, channels_last)
                target = StyleTarget(style.matrix, search_dtype=dtype)

                def step(with_nnfm: bool = False, img: torch.Tensor = img, target: StyleTarget = target) -> None:
                    x = img.clone().requires_grad_(True)
                    feats = vgg(x)
                    loss = nnfm_loss(concat_features(feats), target) if with_nnfm else feats["relu3_3"].mean()
                    loss.backward()

                vgg_s = _time(step, args.repeats)
                full_s = _time(lambda: step(True), args.repeats)
                results[(threads, size, mode)] = vgg_s
                print(f"{threads:>7} {size:>5} {mode:>6} {vgg_s:>10.3f} {full_s:>8.3f}")
    summary = " ".join(f"t{t}_{s}_{m}={v:.3f}s" for (t, s, m), v in results.items())
    print(f"RESULT vgg_fwd_bwd_median {summary}")


if __name__ == "__main__":
    main()
