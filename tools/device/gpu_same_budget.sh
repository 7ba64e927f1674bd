#!/usr/bin/env bash
# Calls on a lent GPU machine (developers only; run from the repository root by the workplace's `device` tool,
# carrying .devdeps/ from tools/device/fetch_debs.sh). Issue 29's same-budget ceiling, more compute for the shipped
# model, and the architecture's own ceiling, one PHASE per call:
#   PHASE=ceiling: builds uplvsm against that machine's CUDA LibTorch 2.x (tools/device/cuda_setup.sh), renders the
#     demo dataset into $B/ds96 (kept for the next call), trains the posed LVSM of the shipped model's size on the
#     shipped model's budget (configs/demo_ceiling_gpu.json: 5375 x 32 = 172000 scenes of 6 targets) while
#     the unit tests build and run at low priority; leaves ceiling.safetensors, the run's newest checkpoint split
#     into 15-MB parts when it could not finish (ceiling_run.tar.part-*, for `--resume auto` elsewhere) and logs.
#   PHASE=longer (the next call, on the warm machine): the shipped model's fourth stage from INIT, the third stage's
#     weights (`git show 5a58744:models/demo.safetensors > .gpuinit/third_stage.safetensors`, carried), with
#     configs/demo_model_stage4_gpu.json; leaves longer.safetensors and logs.
#   (PHASE=encdec, UP-LVSM's encoder-decoder told every camera, went with model.encoder_cameras: commit 8ca59b4.)
# On 2026-11-28 (an H200) the ceiling reached step 5030 of 5375 in a 570-s call (the CLI built in 96 s; the tests beside
# it); `uplvsm train ... --resume auto` on the warm machine ran the rest in 27 s, and the fourth stage's command was
# run by hand there (170 s), as PHASE=longer now runs it.
# BUDGET is the seconds the call may take; training stops 30 s before it whatever its step.
set -uo pipefail
BUDGET=${BUDGET:-560}
PHASE=${PHASE:-ceiling}

# shellcheck source=tools/device/cuda_setup.sh
source tools/device/cuda_setup.sh
DS=$B/ds96
TRAIN_END=$((BUDGET - 30))
train() {  # NAME ARGS...: one training, stopped at TRAIN_END whatever its step
  local name=$1; shift
  timeout -s TERM -k 15 $((TRAIN_END - $(elapsed))) ./$B/uplvsm train --data $DS --device cuda "$@" \
    >"$LOGS/train_$name.log" 2>&1
  log "train $name: rc $? $(tail -c 300 "$LOGS/train_$name.log" | tr '\r' '\n' | tail -1)"
}
keep_run() {  # NAME: metrics, config and weights of /tmp/run_NAME into $OUT/$LOGS
  cp /tmp/run_$1/metrics.jsonl "$LOGS/metrics_$1.jsonl" 2>/dev/null
  cp /tmp/run_$1/config.json "$LOGS/config_$1.json" 2>/dev/null
  cp -r /tmp/run_$1/eval "$LOGS/eval_$1" 2>/dev/null
  ./$B/uplvsm export --checkpoint /tmp/run_$1 --out "$OUT/$1.safetensors" >>"$LOGS/export.log" 2>&1 ||
    log "export $1 failed"
}

if [ "$PHASE" = ceiling ]; then
  start_test_build
  [ -f $DS/test/index.json ] || render_demo_dataset $DS || exit 1
  log "the same-budget ceiling"
  train ceiling --config configs/demo_ceiling_gpu.json --run /tmp/run_ceiling &
  TRAIN_PID=$!
  run_unit_tests_until "$TRAIN_END"
  wait $TRAIN_PID
  keep_run ceiling
  if ! grep -q '"step": *5375' /tmp/run_ceiling/metrics.jsonl 2>/dev/null; then
    log "ceiling stopped early: its run folder comes back in parts"
    tar -C /tmp -cf - run_ceiling/config.json run_ceiling/metrics.jsonl run_ceiling/checkpoints |
      split -b 15M - "$OUT/ceiling_run.tar.part-"
  fi
else
  [ -f $DS/test/index.json ] || render_demo_dataset $DS || exit 1
  INIT=${INIT:-.gpuinit/third_stage.safetensors}
  [ -f "$INIT" ] || { log "INIT $INIT is missing: carry it"; exit 1; }
  log "the shipped model's fourth stage"
  train longer --config configs/demo_model_stage4_gpu.json --init "$INIT" --run /tmp/run_longer
  keep_run longer
fi
ls -la "$OUT"
