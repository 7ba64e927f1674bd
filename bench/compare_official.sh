#!/bin/bash
# The paper_x224 figures of README "Benchmarks" (the issue-9 table against the official PyTorch code): under the
# official numbers' conditions (OpenBLAS's own kernel choice, passive OpenMP, 2 threads), then with the environment
# as it is. Medians and min-max come from --benchmark_repetitions=3; one configuration per process (peak RSS).
# Run from the repository root after `make build`: bench/compare_official.sh | tee bench.log   (about an hour on 2 cores)
set -u
B=${UPLVSM_BENCH:-build/uplvsm_bench}
OFFICIAL=(env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE OMP_WAIT_POLICY=PASSIVE OMP_NUM_THREADS=2)
R3=(--benchmark_repetitions=3)
run() { echo "== $*"; "$@" 2>&1 | grep -E "BM_|BLAS core" | sed 's/ \+/ /g'; }
for prefix in official as-is; do
  if [ "$prefix" = official ]; then P=("${OFFICIAL[@]}"); else P=(); fi
  run "${P[@]}" "$B" --benchmark_filter='MatmulPeak' "${R3[@]}" --benchmark_report_aggregates_only=true
  run "${P[@]}" "$B" --benchmark_filter='Attention/L:(256|512|1280|1536)/'
  run "${P[@]}" "$B" --benchmark_filter='Inference/paper_x224/bf16:0' "${R3[@]}"
  run "${P[@]}" "$B" --benchmark_filter='Inference/paper_x224/bf16:1' "${R3[@]}"
  run "${P[@]}" "$B" --benchmark_filter='RenderInterpolation/paper_x224/bf16:0' "${R3[@]}"
  run "${P[@]}" "$B" --benchmark_filter='TrainStep/paper_x224/bf16:0/ckpt:1/' "${R3[@]}"
  run "${P[@]}" "$B" --benchmark_filter='TrainStep/paper_x224/bf16:1/ckpt:1/' "${R3[@]}"
done
