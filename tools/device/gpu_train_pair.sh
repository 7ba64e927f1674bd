#!/usr/bin/env bash
# One call on a lent GPU machine (developers only; run from the repository root by the workplace's `device` tool,
# carrying .devdeps/ from tools/device/fetch_debs.sh). Issue 29's same-budget comparison: in BUDGET seconds it
#   1. builds uplvsm against that machine's own CUDA LibTorch 2.x (tools/device/cuda_setup.sh) and renders the demo
#      dataset there;
#   2. trains the image-token UP-LVSM recipe (configs/demo_image_tokens_gpu.json) and the posed LVSM ceiling with the
#      same training block (configs/demo_lvsm_gpu.json) side by side, for the same number of steps: MAX_STEPS (3000:
#      192k scenes, the CPU recipe's budget) or fewer, as a short speed probe says fits, the same for both;
#   3. builds and runs the unit tests meanwhile at low priority (CUDA where a test has a CUDA case);
#   4. leaves the weights (weights-only exports) and logs.tar.gz (logs, metrics.jsonl, the steps run, ctest) in $OUT.
set -uo pipefail
BUDGET=${BUDGET:-540}

export_runs() {
  for r in "${RUNS[@]}"; do
    cp /tmp/run_$r/metrics.jsonl "$LOGS/metrics_$r.jsonl" 2>/dev/null
    cp /tmp/run_$r/config.json "$LOGS/config_$r.json" 2>/dev/null
    ./$B/uplvsm export --checkpoint /tmp/run_$r --out "$OUT/$r.safetensors" >>"$LOGS/export.log" 2>&1 ||
      log "export $r failed"
  done
}

# shellcheck source=tools/device/cuda_setup.sh
source tools/device/cuda_setup.sh
start_test_build
DS=/tmp/ds96
render_demo_dataset $DS || exit 1

RUNS=(imgtok lvsm)
# CONFIG_UNPOSED / CONFIG_POSED / MAX_STEPS pick another pair (the same training block in both, for a fair gap).
declare -A CFG=([imgtok]=${CONFIG_UNPOSED:-configs/demo_image_tokens_gpu.json} [lvsm]=${CONFIG_POSED:-configs/demo_lvsm_gpu.json})
MAX_STEPS=${MAX_STEPS:-3000}
log "speed probe: 80 steps of each, side by side"
PROBES=()
for r in "${RUNS[@]}"; do
  ./$B/uplvsm train --config "${CFG[$r]}" --data $DS --device cuda --run /tmp/probe_$r --stop-after 80 \
    >"$LOGS/probe_$r.log" 2>&1 &
  PROBES+=($!)
done
wait "${PROBES[@]}"
TRAIN_END=$((BUDGET - 40))
# Steps/s between the probe's step 20 and its last logged step (metrics.jsonl's train_seconds): the progress bar's
# rate counts the start-up too, and on 2026-11-27 read 4.95 steps/s where the runs then went at 7.0 and 10.1.
RATE=$(for r in "${RUNS[@]}"; do
  python3 -c 'import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
a = next(r for r in rows if r["step"] >= 20); b = rows[-1]
print((b["step"] - a["step"]) / (b["train_seconds"] - a["train_seconds"]))' /tmp/probe_$r/metrics.jsonl
done | sort -g | head -1)
# The same step count for both (the slower one's rate decides), a multiple of 50, at most MAX_STEPS.
STEPS=$(awk -v r="${RATE:-1}" -v t=$((TRAIN_END - $(elapsed) - 15)) -v m="$MAX_STEPS" \
  'BEGIN { s = int(r * t / 50) * 50; print (s > m ? m : s) }')
log "slowest probe rate ${RATE} steps/s; training both for $STEPS steps until t=${TRAIN_END} s"
echo "$STEPS" >"$LOGS/steps.txt"
for r in "${RUNS[@]}"; do
  timeout -s TERM -k 15 $((TRAIN_END - $(elapsed))) ./$B/uplvsm train --config "${CFG[$r]}" --data $DS \
    --device cuda --run /tmp/run_$r --steps "$STEPS" >"$LOGS/train_$r.log" 2>&1 &
done

run_unit_tests_until "$TRAIN_END"
wait
log "training done"
for r in "${RUNS[@]}"; do tail -2 "$LOGS/train_$r.log"; done
export_runs
ls -la "$OUT"
