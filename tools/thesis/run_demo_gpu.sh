#!/usr/bin/env bash
# The pose-noise curve at the demo size, for a lent GPU (docs/research/thesis.md): the ceiling's LVSM
# (configs/demo_ceiling_gpu.json: 96x96, d 128, the shipped model's budget of 5375 x 32) trained at every
# noise level, all levels at once as separate processes on the one GPU (the model is small), scored on clean test
# cameras. UP-LVSM never reads training cameras: the shipped model (models/demo.safetensors, the same budget) stands
# at every level and is scored on the same test scenes.
# Run by the workplace's `device` tool from the repository root, carrying .devdeps/ (tools/device/fetch_debs.sh):
#   tools/thesis/run_demo_gpu.sh     LEVELS (sd; default both readings of the paper's levels), SEED, BUDGET (s)
# Every run stops BUDGET-40 s after the start whatever its step; the same call on the warm machine resumes each from
# its checkpoint (/tmp/pose_noise_demo). $OUT/pose_noise_demo gets each run's result.json, metrics.jsonl and, once all
# runs are done, the study's table.md/csv, psnr.png and curves.png.
set -uo pipefail
BUDGET=${BUDGET:-560}
LEVELS=${LEVELS:-0 0.001 0.01 0.0316228 0.1 0.316228}
SEED=${SEED:-783}
STUDY=/tmp/pose_noise_demo

# shellcheck source=tools/device/cuda_setup.sh
source tools/device/cuda_setup.sh
DS=$B/ds96
[ -f $DS/test/index.json ] || render_demo_dataset $DS || exit 1
study() {  # ARGS...: the pose-noise study of the ceiling's LVSM on the demo dataset, stopped at the budget
  timeout -s TERM -k 15 $((BUDGET - 40 - $(elapsed))) ./$B/uplvsm study pose-noise --device cuda \
    --config configs/demo_ceiling_gpu.json --data $DS --seeds "$SEED" --out $STUDY "$@"
}

log "pose noise at the demo size: levels $LEVELS, seed $SEED"
pids=()
for sd in $LEVELS; do
  study --noise-std "$sd" >"$LOGS/pose_noise_sd$sd.log" 2>&1 &
  pids+=($!)
done
for p in "${pids[@]}"; do wait "$p"; done
done_runs=$(find $STUDY/runs -name result.json 2>/dev/null | wc -l)
log "runs done: $done_runs of $(wc -w <<<"$LEVELS")"
# shellcheck disable=SC2086
[ "$done_runs" -eq "$(wc -w <<<"$LEVELS")" ] && study --noise-std $LEVELS >"$LOGS/pose_noise_report.log" 2>&1

./$B/uplvsm eval --device cuda --checkpoint models/demo.safetensors --data $DS --out /tmp/eval_shipped \
  >"$LOGS/eval_shipped.log" 2>&1
mkdir -p "$OUT/pose_noise_demo"
cp /tmp/eval_shipped/metrics.json "$OUT/pose_noise_demo/shipped_uplvsm_metrics.json" 2>/dev/null
(cd $STUDY && find . -name result.json -o -name metrics.jsonl -o -name 'table.*' -o -name '*.png' -o \
  -name README.md -o -name study.json | tar -cf - -T - | tar -C "$OUT/pose_noise_demo" -xf -)
