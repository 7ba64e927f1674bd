#!/bin/bash
# One sitting of the x224 CPU inference comparison on a 2-core host (its CSV's first line names the CPU and whether
# it has AVX2 / AVX-512; docs/performance.md gives the figures per CPU class): the authors' PyTorch
# code, ONNX Runtime on that model exported to ONNX, and ours (uplvsm_bench's Inference/paper_x224/bf16:0), all
# fp32, batch 1, 2 input views + 3 target views, seconds per target view. The engines ALTERNATE within the sitting:
# --rounds rounds (default 4) of
#     official, ort, ours, ours_noenv        (odd rounds)
#     ours_noenv, ours, ort, official        (even rounds: reversed, so a drift of the host is not one engine's)
# each run a separate process under the same conditions: OMP_NUM_THREADS=2, OMP_WAIT_POLICY=PASSIVE, 2 intra-op
# threads. `ours` runs with the environment as it is (OPENBLAS_* as set), `ours_noenv` with
# `env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE` (a user's environment; docs/performance.md); `official` and `ort`
# run with those two variables unset as well (OpenBLAS's own kernel choice, the official numbers' conditions; ORT
# does not use OpenBLAS). Every process does one untimed warm-up forward and then 3 timed forwards (uplvsm_bench's
# fixed 3 iterations; --time N changes official's and ort's count) and reports the MEAN over the timed forwards in
# seconds per target view (uplvsm_bench's s_per_view counter is that mean; the official and ORT scripts also print
# each run and the median, kept in the logs). Output: one line `engine round s_per_view` per run, a CSV (--out
# FILE: engine,round,position,s_per_view,runs,wall_s,load1_before,started) and the raw logs next to it
# (FILE.logs/ENGINE_rROUND.log: stdout, .log.err: stderr), then per round the ratios ours/ort and ours_noenv/ort
# (the runs adjacent to ORT), official/ours and official/ort, and each engine's median over the rounds. Run it on
# a quiet machine (the 1-minute load average before each run is in the CSV; the smoke test on a busy one cannot
# stand for a result): about 12-15 minutes at 4 rounds on a quiet 2-core host (official ~1 min per process).
#
# Set-up (nothing of it is part of this repository):
#   - the official code: a checkout of github.com/ou524u/Less3Depend (measured at d490397) in $OFFICIAL_DIR;
#     Debian's python3 (torch 1.13) with python3-easydict python3-yaml (python3-onnx for the export's checker);
#   - einops: the real package on $SHIMS / PYTHONPATH, or (the default $SHIMS) bench/official_shims, a stand-in with
#     rearrange / repeat / layers.torch.Rearrange for the patterns bench/official_x224.py --help lists;
#   - onnxruntime-node: mkdir -p /tmp/ort && cd /tmp/ort && npm install onnxruntime-node --ignore-scripts
#     (its install script fetches GPU extras and fails offline; the CPU build ships in the package);
#   - the ONNX model: $ONNX (default /tmp/uplvsm_official_x224.onnx, ~1 GiB), exported before the first round
#     when missing: /usr/bin/python3 bench/official_x224.py --official $OFFICIAL_DIR --shims $SHIMS --export-onnx $ONNX
#   - ours: `make build` (build/uplvsm_bench), or UPLVSM_BENCH=path.
# Command (repository root):
#   OFFICIAL_DIR=/tmp/official ORT_DIR=/tmp/ort UPLVSM_BENCH=build/uplvsm_bench \
#     bench/cpu_sitting.sh --out /tmp/cpu_sitting.csv [--rounds 4] [--time 3] [--engines official,ort,ours,ours_noenv]
#   bench/cpu_sitting.sh --summarize /tmp/cpu_sitting.csv    (the summary of a CSV again, e.g. an interrupted one)
set -uo pipefail
{  # the whole script is read before it runs: editing this file during a sitting cannot change that sitting

OFFICIAL_DIR=${OFFICIAL_DIR:-/tmp/official}
SHIMS=${SHIMS:-$(cd "$(dirname "$0")" && pwd)/official_shims}
ORT_DIR=${ORT_DIR:-/tmp/ort}
UPLVSM_BENCH=${UPLVSM_BENCH:-build/uplvsm_bench}
ONNX=${ONNX:-/tmp/uplvsm_official_x224.onnx}
PYTHON=${PYTHON:-/usr/bin/python3}
NODE=${NODE:-node}
HERE=$(cd "$(dirname "$0")" && pwd)

OUT="" SUMMARIZE="" ROUNDS=4 TIMED=3 ENGINES="official,ort,ours,ours_noenv" WARMUP=1
while [ $# -gt 0 ]; do
  case "$1" in
    --out) OUT=$2; shift 2 ;;
    --summarize) SUMMARIZE=$2; shift 2 ;;
    --rounds) ROUNDS=$2; shift 2 ;;
    --time) TIMED=$2; shift 2 ;;
    --warmup) WARMUP=$2; shift 2 ;;
    --engines) ENGINES=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -uo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "cpu_sitting: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
summarize() {
  echo "== summary ($1)"
  "$PYTHON" - "$1" <<'EOF'
import csv, statistics, sys
rows = [r for r in csv.DictReader(l for l in open(sys.argv[1]) if not l.startswith("#"))]
value = {}
for r in rows:
    try:
        value[(r["engine"], int(r["round"]))] = float(r["s_per_view"])
    except ValueError:
        pass
rounds = sorted({int(r["round"]) for r in rows})
engines = list(dict.fromkeys(r["engine"] for r in rows))
pairs = [("ours", "ort"), ("ours_noenv", "ort"), ("official", "ours"), ("official", "ort")]
ratios = {p: [] for p in pairs}
for rnd in rounds:
    parts = []
    for a, b in pairs:
        if (a, rnd) in value and (b, rnd) in value:
            ratio = value[(a, rnd)] / value[(b, rnd)]
            ratios[(a, b)].append(ratio)
            parts.append(f"{a}/{b} {ratio:.3f}")
    print(f"round {rnd}: " + ", ".join(parts))
for e in engines:
    xs = [value[(e, rnd)] for rnd in rounds if (e, rnd) in value]
    if xs:
        print(f"{e}: median {statistics.median(xs):.4f} s/view over {len(xs)} rounds "
              f"(min {min(xs):.4f}, max {max(xs):.4f})")
for (a, b), xs in ratios.items():
    if xs:
        print(f"{a}/{b}: median {statistics.median(xs):.3f} (min {min(xs):.3f}, max {max(xs):.3f}) "
              f"over {len(xs)} rounds")
EOF
}
if [ -n "$SUMMARIZE" ]; then summarize "$SUMMARIZE"; exit; fi
[ -n "$OUT" ] || { echo "cpu_sitting: --out FILE is required" >&2; exit 2; }
IFS=, read -r -a ORDER <<< "$ENGINES"

need() { [ -e "$1" ] || { echo "cpu_sitting: missing $1 ($2)" >&2; exit 1; }; }
for e in "${ORDER[@]}"; do
  case "$e" in
    official) need "$OFFICIAL_DIR/src/model/uplvsm.py" "OFFICIAL_DIR" ;;
    ort) need "$ORT_DIR/node_modules/onnxruntime-node" "ORT_DIR: npm install onnxruntime-node --ignore-scripts" ;;
    ours|ours_noenv) need "$UPLVSM_BENCH" "UPLVSM_BENCH: make build" ;;
    *) echo "cpu_sitting: unknown engine $e" >&2; exit 2 ;;
  esac
done
if [[ ",$ENGINES," == *,ort,* ]] && [ ! -f "$ONNX" -o ! -f "$ONNX.io/io.json" ]; then
  echo "== exporting $ONNX (once, before the sitting)"
  PYTHONPATH="$SHIMS${PYTHONPATH:+:$PYTHONPATH}" OMP_NUM_THREADS=2 OMP_WAIT_POLICY=PASSIVE \
    "$PYTHON" "$HERE/official_x224.py" --official "$OFFICIAL_DIR" --export-onnx "$ONNX" || exit 1
fi

LOGS="$OUT.logs"
mkdir -p "$LOGS"
# env's -u options must precede its assignments
ASIS=(env OMP_NUM_THREADS=2 OMP_WAIT_POLICY=PASSIVE)
NOENV=(env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE OMP_NUM_THREADS=2 OMP_WAIT_POLICY=PASSIVE)
{
  echo "# cpu_sitting $(date -Is) on $(hostname): $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | xargs)," \
    "$(nproc) cpus, avx2=$(grep -qw avx2 /proc/cpuinfo && echo yes || echo no)," \
    "avx512f=$(grep -qw avx512f /proc/cpuinfo && echo yes || echo no);" \
    "OPENBLAS_CORETYPE=${OPENBLAS_CORETYPE-(unset)} OPENBLAS_L2_SIZE=${OPENBLAS_L2_SIZE-(unset)}"
  echo "engine,round,position,s_per_view,runs,wall_s,load1_before,started"
} > "$OUT"
head -1 "$OUT"

# One engine's process; stdout to $2, stderr to $2.err.
run_engine() {
  local engine=$1 log=$2
  case "$engine" in
    official)
      "${NOENV[@]}" PYTHONPATH="$SHIMS${PYTHONPATH:+:$PYTHONPATH}" "$PYTHON" "$HERE/official_x224.py" \
        --official "$OFFICIAL_DIR" --threads 2 --warmup "$WARMUP" --time "$TIMED" > "$log" 2> "$log.err" ;;
    ort)
      "${NOENV[@]}" "$NODE" "$HERE/ort_x224.mjs" "$ONNX" --ort-dir "$ORT_DIR" --threads 2 \
        --warmup "$WARMUP" --time "$TIMED" > "$log" 2> "$log.err" ;;
    ours)
      "${ASIS[@]}" "$UPLVSM_BENCH" --benchmark_filter='Inference/paper_x224/bf16:0/' --benchmark_format=json \
        --benchmark_repetitions=1 > "$log" 2> "$log.err" ;;
    ours_noenv)
      "${NOENV[@]}" "$UPLVSM_BENCH" --benchmark_filter='Inference/paper_x224/bf16:0/' \
        --benchmark_format=json --benchmark_repetitions=1 > "$log" 2> "$log.err" ;;
  esac
}

# "mean runs" from a log: the official/ORT scripts print `run i X s/view` and `mean X s/view`; uplvsm_bench prints
# its runtime set-up and then JSON with the s_per_view counter.
parse_log() {
  "$PYTHON" - "$1" "$2" <<'EOF'
import json, re, sys
engine, path = sys.argv[1], sys.argv[2]
text = open(path, errors="replace").read()
if engine.startswith("ours"):
    report = json.loads(text[text.index("{\n"):])
    runs = [b for b in report["benchmarks"] if b.get("run_type") == "iteration" and "s_per_view" in b]
    print(f"{runs[0]['s_per_view']:.4f}" if len(runs) == 1 else "NA", "")
else:
    mean = re.findall(r"^mean ([0-9.]+) s/view$", text, re.M)
    runs = re.findall(r"^run \d+ ([0-9.]+) s/view$", text, re.M)
    print(mean[-1] if mean else "NA", " ".join(runs))
EOF
}

for ((round = 1; round <= ROUNDS; round++)); do
  seq=("${ORDER[@]}")
  if ((round % 2 == 0)); then
    seq=(); for ((i = ${#ORDER[@]} - 1; i >= 0; i--)); do seq+=("${ORDER[$i]}"); done
  fi
  position=0
  for engine in "${seq[@]}"; do
    position=$((position + 1))
    log="$LOGS/${engine}_r${round}.log"
    load1=$(cut -d' ' -f1 /proc/loadavg)
    started=$(date -Is)
    t0=$EPOCHREALTIME
    run_engine "$engine" "$log"
    rc=$?
    wall=$(awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }')
    spv=NA runs="rc=$rc"
    if [ $rc -eq 0 ]; then read -r spv runs < <(parse_log "$engine" "$log" 2>>"$log.err" || echo NA); fi
    printf '%s %d %s\n' "$engine" "$round" "$spv"
    printf '%s,%d,%d,%s,%s,%s,%s,%s\n' "$engine" "$round" "$position" "$spv" "$runs" "$wall" "$load1" "$started" \
      >> "$OUT"
  done
done

summarize "$OUT"
exit
}
