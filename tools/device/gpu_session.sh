#!/usr/bin/env bash
# One call on a lent GPU machine (developers only: the workplace's `device` tool runs it from the repository root,
# carrying .devdeps/ from tools/device/fetch_debs.sh). In BUDGET seconds it
#   1. builds uplvsm against that machine's own CUDA LibTorch 2.x (torch.utils.cmake_prefix_path);
#   2. renders the demo dataset on CUDA and trains three demo-size models on the GPU side by side (UP-LVSM,
#      UP-LVSM with the encoder's image tokens, posed LVSM), sized to the time left after a short speed probe;
#   3. runs the unit tests meanwhile (CUDA where a test has a CUDA case), then times the x224 benchmarks on CUDA;
#   4. leaves the weights (weights-only exports) and logs.tar.gz (every log, metrics.jsonl, ctest, bench JSON) in $OUT.
# A carried .fixtures/ (tools/device/pack_fixtures.sh: the part of the fixture pack that fits a call) is used as the
# fixture pack; without it the fixture tests skip.
set -uo pipefail
BUDGET=${BUDGET:-540}
BATCH=${BATCH:-64}
# shellcheck source=tools/device/cuda_setup.sh
source tools/device/cuda_setup.sh
log "build tests and benchmarks (background)"
(cmake --build $B -j 10 -- -k 0 >"$LOGS/build_all.log" 2>&1; echo "rc $?" >>"$LOGS/build_all.log") &
BUILD_PID=$!

DS=/tmp/ds96
render_demo_dataset $DS || exit 1

RUNS=(up imgtok lvsm)
declare -A CFG=([up]="--config configs/demo.json" [imgtok]="--config configs/demo.json --set model.keep_image_tokens=true"
                [lvsm]="--config configs/demo.json --set model.variant=lvsm --set model.transformer.n_layer=7")
COMMON="--data $DS --device cuda --set training.batch_size=$BATCH --set training.loader_threads=4 \
  --set training.eval_every=0 --set training.checkpoint_every=500 --set training.keep_checkpoints=1"
log "speed probe: 60 steps of each, side by side"
P0=$(date +%s)
for r in "${RUNS[@]}"; do
  # shellcheck disable=SC2086
  ./$B/uplvsm train ${CFG[$r]} $COMMON --run /tmp/probe_$r --stop-after 60 >"$LOGS/probe_$r.log" 2>&1 &
done
wait $(jobs -p | grep -v "^$BUILD_PID$")
PROBE=$(($(date +%s) - P0))
TRAIN_END=$((BUDGET - 70))
# The slowest run's own rate (its progress line), not the probe's wall time, which counts the start-up too; the
# early steps are slower than the rest, which makes up for the unit tests sharing the machine later.
RATE=$(for f in "$LOGS"/probe_*.log; do grep -o "[0-9.]* step/s" "$f" | tail -1; done | awk '{print $1}' |
  sort -g | head -1)
STEPS=$(awk -v r="${RATE:-1}" -v t=$((TRAIN_END - $(elapsed) - 10)) 'BEGIN { s = int(r * t); print (s > 20000 ? 20000 : s) }')
log "probe took ${PROBE} s for 60 steps (slowest run ${RATE} steps/s); training $STEPS steps at batch $BATCH until t=${TRAIN_END} s"
for r in "${RUNS[@]}"; do
  # shellcheck disable=SC2086
  timeout -s TERM -k 20 $((TRAIN_END - $(elapsed))) ./$B/uplvsm train ${CFG[$r]} $COMMON --run /tmp/run_$r \
    --steps "$STEPS" >"$LOGS/train_$r.log" 2>&1 &
done

wait $BUILD_PID
log "build: $(tail -1 "$LOGS/build_all.log"); unit tests (-j 6)"
CTEST_SECONDS=$((TRAIN_END - $(elapsed) - 5))
nice -n 10 timeout $((CTEST_SECONDS > 30 ? CTEST_SECONDS : 30)) ctest --test-dir $B -L unit -j 6 --timeout 240 \
  --output-on-failure >"$LOGS/ctest.log" 2>&1
log "ctest: $(grep -E "tests passed|tests failed" "$LOGS/ctest.log")"
grep -A200 "The following tests FAILED" "$LOGS/ctest.log" | head -60
wait
log "training done"
for r in "${RUNS[@]}"; do
  tail -3 "$LOGS/train_$r.log"
  cp /tmp/run_$r/metrics.jsonl "$LOGS/metrics_$r.jsonl" 2>/dev/null
  cp /tmp/run_$r/config.json "$LOGS/config_$r.json" 2>/dev/null
  ./$B/uplvsm export --checkpoint /tmp/run_$r --out "$OUT/$r.safetensors" >>"$LOGS/export.log" 2>&1 ||
    log "export $r failed"
done
log "x224 benchmarks on CUDA"
UPLVSM_BENCH_DEVICE=cuda timeout $((BUDGET - $(elapsed) - 5)) ./$B/uplvsm_bench \
  --benchmark_filter='MatmulPeak|Inference/paper_x224|TrainStep/paper_x224/bf16:[01]/ckpt:0/' \
  --benchmark_out="$LOGS/bench_cuda.json" --benchmark_out_format=json 2>&1 | tee "$LOGS/bench_cuda.txt" | tail -12
