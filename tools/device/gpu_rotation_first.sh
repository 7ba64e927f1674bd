#!/usr/bin/env bash
# One call on a lent GPU machine (developers only; run from the repository root by the workplace's `device` tool,
# carrying .devdeps/ from tools/device/fetch_debs.sh and .gpuinit/ with INIT). Issue 29's rotation-first recipe
# with GPU compute: in BUDGET seconds it
#   1. builds uplvsm against that machine's own CUDA LibTorch 2.x (tools/device/cuda_setup.sh) and renders the demo
#      dataset there;
#   2. trains, side by side: `long`, the second stage from INIT (a first stage trained here on the CPU, exported
#      weights-only) with configs/demo_rotation_first_long_gpu.json for as many steps (a multiple of 250, at most
#      MAX_STEPS, the config's 4000) as a short speed probe says fit (on 2026-11-27 all 4000: the shipped model);
#      and `seed`, both stages from scratch with another seed (configs/demo_rotation_first_gpu.json, then
#      configs/demo_rotation_first_release_gpu.json from it), SETS's --set's added to both (e.g. the block split
#      "--set model.transformer.encoder_n_layer=1 --set model.transformer.decoder_n_layer=5", docs/demo.md's
#      *Where the gap is, at the demo size*);
#   3. builds and runs the unit tests meanwhile at low priority (CUDA where a test has a CUDA case);
#   4. leaves the weights (weights-only exports) and logs.tar.gz (logs, metrics.jsonl, the steps run, ctest) in $OUT.
# Before it, here: `uplvsm export --checkpoint R/rotation --out .gpuinit/stage1_777.safetensors` (.gpuinit/ listed in
# .git/info/exclude); then the device tool runs `BUDGET=550 bash tools/device/gpu_rotation_first.sh`, carrying
# .devdeps and .gpuinit (on 2026-11-27: 445 s of a 600-s call).
set -uo pipefail
BUDGET=${BUDGET:-540}
INIT=${INIT:-.gpuinit/stage1_777.safetensors}
SEED=${SEED:-778}
MAX_STEPS=${MAX_STEPS:-4000}
[ -f "$INIT" ] || { echo "INIT $INIT is missing: carry it"; exit 1; }

# shellcheck source=tools/device/cuda_setup.sh
source tools/device/cuda_setup.sh
start_test_build
DS=/tmp/ds96
render_demo_dataset $DS || exit 1
TRAIN_END=$((BUDGET - 40))
train() {  # NAME ARGS...: one training, stopped at TRAIN_END whatever its step
  local name=$1; shift
  [ $((TRAIN_END - $(elapsed))) -gt 30 ] || { log "train $name: no time left, skipped"; return; }
  timeout -s TERM -k 15 $((TRAIN_END - $(elapsed))) ./$B/uplvsm train --data $DS --device cuda "$@" \
    >"$LOGS/train_$name.log" 2>&1
  log "train $name: rc $? $(tail -c 300 "$LOGS/train_$name.log" | tr '\r' '\n' | tail -1)"
}

log "seed $SEED: both stages (background) ${SETS:-}"
# shellcheck disable=SC2086  # SETS is a list of words
( train seed_stage1 --config configs/demo_rotation_first_gpu.json --run /tmp/run_seed_stage1 --set training.seed=$SEED \
    ${SETS:-}
  train seed_stage2 --config configs/demo_rotation_first_release_gpu.json --init /tmp/run_seed_stage1 \
    --run /tmp/run_seed_stage2 ${SETS:-} ) &
SEED_PID=$!

log "speed probe of the long stage, 80 steps beside the seed's"
./$B/uplvsm train --config configs/demo_rotation_first_long_gpu.json --init "$INIT" --data $DS --device cuda \
  --run /tmp/probe_long --stop-after 80 --set training.eval_every=0 >"$LOGS/probe_long.log" 2>&1
# Steps/s between step 20 and the last logged step (metrics.jsonl's train_seconds), shared with the seed's run: a
# lower bound once that one ends.
RATE=$(python3 -c 'import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if "\"loss\"" in l]
a = next(r for r in rows if r["step"] >= 20); b = rows[-1]
print((b["step"] - a["step"]) / (b["train_seconds"] - a["train_seconds"]))' /tmp/probe_long/metrics.jsonl)
STEPS=$(awk -v r="${RATE:-1}" -v t=$((TRAIN_END - $(elapsed) - 30)) -v m="$MAX_STEPS" \
  'BEGIN { s = int(r * t / 250) * 250; print (s > m ? m : (s < 250 ? 250 : s)) }')
log "probe rate ${RATE} steps/s; the long stage runs $STEPS steps until t=${TRAIN_END} s"
echo "$STEPS" >"$LOGS/steps_long.txt"
train long --config configs/demo_rotation_first_long_gpu.json --init "$INIT" --run /tmp/run_long --steps "$STEPS" &
LONG_PID=$!

run_unit_tests_until "$TRAIN_END"
wait $SEED_PID $LONG_PID
log "training done"
for r in long seed_stage1 seed_stage2; do
  cp /tmp/run_$r/metrics.jsonl "$LOGS/metrics_$r.jsonl" 2>/dev/null
  cp /tmp/run_$r/config.json "$LOGS/config_$r.json" 2>/dev/null
  ./$B/uplvsm export --checkpoint /tmp/run_$r --out "$OUT/$r.safetensors" >>"$LOGS/export.log" 2>&1 ||
    log "export $r failed"
done
ls -la "$OUT"
