#!/usr/bin/env python3
"""The same x224 forward timed from Python (`import uplvsm`, as the README's example uses it) and from C++
(uplvsm_bench's Inference/paper_x224) in one run and one environment: batch 1, 2 input views + 3 target views, the
estimator reading the targets, a randomly initialised model, fp32 and bf16 autocast, no gradients.

    PYTHONPATH=build/python /usr/bin/python3 bench/python_vs_cpp.py [--build build] [--repetitions 3]

Prints seconds per target view (median and min-max of the repetitions) for both and their ratio. `make bench` runs
it after the C++ benchmarks, as the environment is and without this machine's OPENBLAS_* overrides.
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import time

import uplvsm  # before torch: the module's runtime defaults, as a user gets them
import torch

REPO = pathlib.Path(__file__).resolve().parents[1]
INPUTS, TARGETS = 2, 3


def python_seconds_per_view(config, amp, repetitions):
    model = uplvsm.init(str(config))
    size = model.config["model"]["image_size"]
    generator = torch.Generator().manual_seed(0)
    images = torch.rand(1, INPUTS + TARGETS, 3, size, size, generator=generator)
    fxfycxcy = torch.tensor([0.9 * size, 0.9 * size, 0.5 * size, 0.5 * size]).expand(1, INPUTS + TARGETS, 4).contiguous()

    def run():
        with torch.no_grad():
            return model.forward(images[:, :INPUTS], fxfycxcy[:, :INPUTS], images[:, INPUTS:], fxfycxcy[:, INPUTS:],
                                 amp=amp)["render"]

    run()  # warm-up, as the C++ benchmark does
    times = []
    for _ in range(repetitions):
        t0 = time.perf_counter()
        run()
        times.append((time.perf_counter() - t0) / TARGETS)
    return times


def cpp_seconds_per_view(build, bf16, repetitions):
    out = subprocess.run(
        [str(build / "uplvsm_bench"), f"--benchmark_filter=Inference/paper_x224/bf16:{int(bf16)}/",
         f"--benchmark_repetitions={repetitions}", "--benchmark_min_time=0.01", "--benchmark_format=json"],
        check=True, capture_output=True, text=True).stdout
    report = json.loads(out[out.index("{"):])  # the binary prints its runtime set-up first
    runs = [b for b in report["benchmarks"] if b.get("run_type") == "iteration"]
    return [b["s_per_view"] for b in runs]


def describe(times):
    return f"{statistics.median(times):.3f} s/view ({min(times):.3f}-{max(times):.3f})"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--build", type=pathlib.Path, default=REPO / "build", help="build tree with uplvsm_bench")
    parser.add_argument("--config", type=pathlib.Path, default=REPO / "configs" / "paper_x224.json")
    parser.add_argument("--repetitions", type=int, default=3)
    args = parser.parse_args()
    info = uplvsm.runtime_info()
    env = {k: os.environ.get(k, "(unset)") for k in ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE", "OMP_NUM_THREADS")}
    print(f"python_vs_cpp: {info['threads']} threads, BLAS core {info['blas_core']}, {env}")
    for amp in ("none", "bf16"):
        py = python_seconds_per_view(args.config, amp, args.repetitions)
        cpp = cpp_seconds_per_view(args.build, amp == "bf16", args.repetitions)
        ratio = statistics.median(py) / statistics.median(cpp)
        label = "fp32" if amp == "none" else "bf16"
        print(f"  x224 {label}: Python {describe(py)} | C++ {describe(cpp)} | Python / C++ {ratio:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
