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
T0=$(date +%s)
BUDGET=${BUDGET:-540}
BATCH=${BATCH:-64}
OUT=${OUT:-/tmp/gpu_out}
LOGS=/tmp/gpu_logs
B=build-cuda
mkdir -p "$OUT" "$LOGS"
elapsed() { echo $(($(date +%s) - T0)); }
log() { echo "[$(elapsed) s] $*" | tee -a "$LOGS/session.log"; }
finish() {
  tar -C /tmp -czf "$OUT/logs.tar.gz" gpu_logs 2>/dev/null
  log "finished"
}
trap finish EXIT

{ nvidia-smi; python3 -c 'import torch; print("torch", torch.__version__, "cuda", torch.version.cuda, torch.cuda.get_device_name(0))'
  g++ --version | head -1; cmake --version | head -1; echo "ninja $(ninja --version)"; echo "cores $(nproc)"; } \
  >"$LOGS/machine.txt" 2>&1
tail -6 "$LOGS/machine.txt"

# The build's Debian packages, unpacked away from / (they must not replace the image's own libraries).
D=/tmp/deps
mkdir -p $D
for f in .devdeps/*.deb; do dpkg -x "$f" $D || exit 1; done
rm -f $D/usr/lib/x86_64-linux-gnu/libz.a  # FindZLIB may pick the static one, which a shared library cannot take
export PKG_CONFIG=$D/usr/bin/pkgconf PKG_CONFIG_SYSROOT_DIR=$D
export PKG_CONFIG_LIBDIR=$D/usr/lib/x86_64-linux-gnu/pkgconfig:$D/usr/share/pkgconfig
# pkgconf drops -I/usr/include as a system path before the sysroot is applied; keep every flag.
export PKG_CONFIG_SYSTEM_INCLUDE_PATH=/nonexistent PKG_CONFIG_SYSTEM_LIBRARY_PATH=/nonexistent
export PKG_CONFIG_ALLOW_SYSTEM_CFLAGS=1 PKG_CONFIG_ALLOW_SYSTEM_LIBS=1
# LibTorch 2.x ships its own (newer) fmt headers in its include directory; Debian's spdlog 1.10 needs its fmt 9, so
# those two come first. Gloo lives inside libtorch_cpu there: a symbol c10d's header calls into may not be exported,
# which only matters to multi-process training, so executables may link with it unresolved (ldd -r lists it).
mkdir -p /tmp/fmtinc && ln -sfn $D/usr/include/fmt /tmp/fmtinc/fmt && ln -sfn $D/usr/include/spdlog /tmp/fmtinc/spdlog
# The image has libjpeg 8's headers on a system path: libjpeg62's must win, or the library refuses the caller.
for h in jpeglib.h jmorecfg.h jerror.h x86_64-linux-gnu/jconfig.h; do ln -sfn $D/usr/include/$h /tmp/fmtinc/; done
[ -d $B ] && grep -l "io/image.cpp" $B/CMakeFiles/uplvsm.dir/Unity/*.cxx 2>/dev/null | sed 's/$/.o/' | xargs -r rm -f
FIXTURES=/nonexistent/fixtures
[ -d .fixtures ] && FIXTURES=$PWD/.fixtures
TORCH_PREFIX=$(python3 -c 'import torch; print(torch.utils.cmake_prefix_path)')
NCCL_INC=$(python3 -c 'import nvidia.nccl, os; print(os.path.join(list(nvidia.nccl.__path__)[0], "include"))' 2>/dev/null)
[ -f "$NCCL_INC/nccl.h" ] && NCCL_FLAG="-isystem $NCCL_INC" || NCCL_FLAG=""
log "configure against $TORCH_PREFIX"
cmake -S . -B $B -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$TORCH_PREFIX;$D/usr" \
  -DZLIB_LIBRARY_RELEASE=$(ls /usr/lib/x86_64-linux-gnu/libz.so.1 $D/lib/x86_64-linux-gnu/libz.so.1 2>/dev/null | head -1) -DCMAKE_CXX_FLAGS="-I/tmp/fmtinc $NCCL_FLAG" -DCMAKE_EXE_LINKER_FLAGS="-Wl,--allow-shlib-undefined" \
  -DUPLVSM_WITH_FFMPEG=OFF -DUPLVSM_BUILD_PYTHON=OFF -DUPLVSM_FIXTURES="$FIXTURES" \
  -DTORCH_CUDA_ARCH_LIST=9.0 >"$LOGS/configure.log" 2>&1 || { tail -60 "$LOGS/configure.log"; exit 1; }
export LD_LIBRARY_PATH=$D/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
log "build the CLI"
cmake --build $B -j "$(nproc)" --target uplvsm_cli -- -k 0 >"$LOGS/build_cli.log" 2>&1 ||
  { grep -E "error:|undefined reference" "$LOGS/build_cli.log" | sort | uniq -c | sort -rn | head -40; exit 1; }
ldd -r ./$B/uplvsm 2>&1 | grep -i undefined | head -5 | tee "$LOGS/ldd_undefined.txt"
./$B/uplvsm info >"$LOGS/info.txt" 2>&1
grep -E "LibTorch|CUDA" "$LOGS/info.txt"
log "build tests and benchmarks (background)"
(cmake --build $B -j 10 -- -k 0 >"$LOGS/build_all.log" 2>&1; echo "rc $?" >>"$LOGS/build_all.log") &
BUILD_PID=$!

log "dataset"
DS=/tmp/ds96
./$B/uplvsm make-dataset --config configs/demo.json --out $DS --device cuda >"$LOGS/dataset.log" 2>&1 ||
  { log "make-dataset on cuda failed: $(tail -3 "$LOGS/dataset.log")"; rm -rf $DS;
    ./$B/uplvsm make-dataset --config configs/demo.json --out $DS --device cpu >>"$LOGS/dataset.log" 2>&1 || exit 1; }

RUNS=(up imgtok lvsm)
declare -A CFG=([up]="--config configs/demo.json" [imgtok]="--config configs/demo.json --set model.keep_image_tokens=true"
                [lvsm]="--config configs/demo_lvsm.json")
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
# 2026-11-26: in-process tests that wrote a file and then removed its directory crashed there (the CLI did not);
# a backtrace says where.
cuda-gdb -q -batch -ex run -ex bt --args ./$B/test_io --gtest_filter=AtomicFile.WriteReadAndCreateParents \
  >"$LOGS/segv_backtrace.txt" 2>&1
grep -E "^#[0-9]" "$LOGS/segv_backtrace.txt" | head -12
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
