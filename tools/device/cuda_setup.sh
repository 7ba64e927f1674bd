# shellcheck shell=bash
# Sourced by the GPU-session scripts (tools/device/gpu_*.sh), never run alone: records the machine, unpacks the carried
# .devdeps/ (tools/device/fetch_debs.sh) away from /, configures $B against that machine's own CUDA LibTorch 2.x
# (torch.utils.cmake_prefix_path) and builds the CLI; exits with the compiler's errors when that fails. Defines T0
# (the session's start), OUT, LOGS (packed into $OUT/logs.tar.gz on exit), B (the build folder), elapsed, log and
# render_demo_dataset DIR (make demo's 96x96 dataset, rendered on CUDA, on the CPU if that fails),
# start_test_build and run_unit_tests_until END (the tests built and run at low priority beside training, within the
# caller's BUDGET); leaves LD_LIBRARY_PATH pointing at the unpacked libraries.
T0=$(date +%s)
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

render_demo_dataset() {
  log "dataset"
  ./$B/uplvsm make-dataset --config configs/demo.json --out "$1" --device cuda >"$LOGS/dataset.log" 2>&1 && return 0
  log "make-dataset on cuda failed: $(tail -3 "$LOGS/dataset.log")"
  rm -rf "$1"
  ./$B/uplvsm make-dataset --config configs/demo.json --out "$1" --device cpu >>"$LOGS/dataset.log" 2>&1
}

start_test_build() {  # in the background, stopped 45 s before BUDGET; sets BUILD_PID
  log "build tests (background, low priority, stopped at the end of training)"
  (nice -n 19 timeout $((BUDGET - 45 - $(elapsed))) cmake --build $B -j 4 -- -k 0 >"$LOGS/build_all.log" 2>&1
    echo "rc $?" >>"$LOGS/build_all.log") &
  BUILD_PID=$!
}

run_unit_tests_until() {  # END: once that build is done, the unit tests (CUDA cases included) until END s
  wait "$BUILD_PID"
  log "build: $(tail -1 "$LOGS/build_all.log"); unit tests (-j 4, low priority)"
  local seconds=$(($1 - $(elapsed) - 5))
  [ "$seconds" -gt 30 ] && nice -n 19 timeout "$seconds" ctest --test-dir $B -L unit -j 4 --timeout 200 \
    --output-on-failure >"$LOGS/ctest.log" 2>&1
  log "ctest: $(grep -E "tests passed|tests failed" "$LOGS/ctest.log" 2>/dev/null)"
  grep -A40 "The following tests FAILED" "$LOGS/ctest.log" 2>/dev/null | head -40
}
