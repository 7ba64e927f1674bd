#!/usr/bin/env bash
# The paper's thesis at `tiny` on the CPU (docs/research/thesis.md): the pose-noise curve, whole-split against
# chunk-pair shuffling, and the scaling table. Every study skips runs whose result.json exists and resumes a run
# from its last checkpoint, so this script continues where it stopped (a fresh machine: the same command).
#   tools/thesis/run_tiny.sh [pose-noise|shuffle|scaling|scaling-exact|scaling-noise|scaling-budget|all]
#   tools/thesis/run_tiny.sh [sfm-data|sfm-exact|sfm-noise|sfm]   (issue 83's study, not part of all: below)
#   (default all; OUT=out/thesis, THREADS=1)
# Two cores: run it twice at once, SEEDS=777 and SEEDS=778 (distinct run folders), then once with both seeds to
# write the combined tables and plots (every run is then found done); the scaling studies instead run scaling-exact
# and scaling-noise at once (SEEDS=777), then SEEDS=778 SUBSETS="125 8000" scaling-exact beside SEEDS=777
# scaling-budget, and SEEDS=778 SUBSETS=8000 NOISE_CONFIGS=configs/tiny_lvsm.json scaling-noise (LVSM's lead over
# UP-LVSM at σ 0.1).
# REPORT_ONLY=1 writes a study's tables and plots from the runs done so far (the others "(not run)") without training;
# PUBLISH=1 then copies what the page reads (table.csv/.md, scenes.csv, stats.csv, curves.csv, levelling.md) into
# docs/research/thesis/<study>/. FROM_DOCS=1 redraws each committed study's table.md and stats.csv from its committed
# table.csv (and scenes.csv), reading no run folder (scaling-short: issue 72's earlier growing-budget study, only so).
# The page's figures: /usr/bin/python3 tools/thesis/plot_thesis.py (from the committed files alone).
#
# Issue 83, the paper's claim as stated: with SfM-estimated cameras the less a model depends on them the more it gains
# from data, while with exact cameras LVSM and UP-LVSM gain alike. UP-LVSM beside the posed models on exact cameras
# (sfm-exact, out/thesis/sfm_exact) and the posed models with SfM-like noise on their training cameras, sigma
# SFM_SIGMA = 0.01 (sfm-noise, out/thesis/sfm_noise0.01: 1.8 degrees of rotation and 1.6 % of the cameras' spread in
# translation per camera, docs/research/thesis.md section 4); 32 / 125 / 2000 / 8000 rooms at 8000 steps; three
# seeds at the end subsets, one between; scored on TEST_ROOMS = 1024 test rooms (the first 48 those of every earlier
# figure), each run's per-scene scores kept (scenes.csv) so every interval also redraws the test rooms.
# Cost (issue 72's runs, one core each, two at once): ~25 min a run up to 2000 rooms, ~38 min on 8000, ~1.5 min to
# score 1024 rooms. In this order, each round two shells at once (one per core); a round ends when both are done:
#   once:    tools/thesis/run_tiny.sh sfm-data        (the 1024 test rooms; rooms_8000 too where missing, ~30 min)
#   round 1: SEEDS="777 778 779" SUBSETS="32 8000" SFM_EXACT_CONFIGS=configs/tiny.json tools/thesis/run_tiny.sh sfm-exact
#            SEEDS="777 778 779" SUBSETS="32 8000" SFM_NOISE_CONFIGS=configs/tiny_lvsm.json tools/thesis/run_tiny.sh sfm-noise
#   round 2: SEEDS="777 778 779" SUBSETS="32 8000" SFM_EXACT_CONFIGS=configs/tiny_lvsm.json tools/thesis/run_tiny.sh sfm-exact
#            SEEDS=777 SUBSETS="125 2000" SFM_EXACT_CONFIGS=configs/tiny.json tools/thesis/run_tiny.sh sfm-exact &&
#            SEEDS=777 SUBSETS="125 2000" SFM_NOISE_CONFIGS=configs/tiny_lvsm.json tools/thesis/run_tiny.sh sfm-noise
#   then:    REPORT_ONLY=1 PUBLISH=1 tools/thesis/run_tiny.sh sfm && /usr/bin/python3 tools/thesis/plot_thesis.py
# Rounds 1-2: 22 runs, ~11.7 core-hours (~6.6 h on two cores). Optional round 3, PT-LVSM (the middle of the
# dependence scale) and LVSM's middle subsets, ~9.3 core-hours more: SFM_NOISE_CONFIGS=configs/tiny_ptlvsm.json and
# SFM_EXACT_CONFIGS=configs/tiny_ptlvsm.json as in round 1, then SEEDS=777 SUBSETS="125 2000" for both and for
# SFM_EXACT_CONFIGS=configs/tiny_lvsm.json.
set -euo pipefail
cd "$(dirname "$0")/../.."
UPLVSM=${UPLVSM:-build/uplvsm}
OUT=${OUT:-out/thesis}
DOCS=docs/research/thesis
THREADS=${THREADS:-1}
STEPS=${STEPS:-4000}
SCALE_STEPS=${SCALE_STEPS:-8000}  # every scaling run's budget (issue 72: fixed, large enough for 8000 rooms)
SEEDS_GIVEN=${SEEDS:-}
read -r -a SEEDS <<<"${SEEDS:-777 778}"
WHAT=${1:-all}
COMMON=(--threads "$THREADS" --seeds "${SEEDS[@]}" --set training.eval_every=1000 --set training.checkpoint_every=500)
wants() { for w in "$@"; do [ "$WHAT" = "$w" ] && return 0; done; return 1; }

# One study: `grid NAME KIND ARGS...` is `uplvsm study KIND ARGS --out $OUT/NAME`, with REPORT_ONLY, PUBLISH and
# FROM_DOCS as the header says.
grid() {
  local name=$1 kind=$2
  shift 2
  if [ -n "${FROM_DOCS:-}" ]; then
    if [ ! -f "$DOCS/$name/table.csv" ]; then echo "run_tiny: no $DOCS/$name/table.csv, skipped" && return; fi
    $UPLVSM study "$kind" "$@" --report-only --from-table "$DOCS/$name/table.csv" --out "$OUT/from_docs/$name"
    cp "$OUT/from_docs/$name/table.md" "$OUT/from_docs/$name/stats.csv" "$DOCS/$name/"
    return
  fi
  $UPLVSM study "$kind" "$@" ${REPORT_ONLY:+--report-only} --out "$OUT/$name"
  if [ -n "${PUBLISH:-}" ]; then
    mkdir -p "$DOCS/$name"
    for f in table.csv table.md scenes.csv stats.csv curves.csv levelling.md; do
      if [ -f "$OUT/$name/$f" ]; then cp "$OUT/$name/$f" "$DOCS/$name/"; fi
    done
  fi
}

# 400 training and 48 test rooms (configs/tiny.json's dataset section), the data of every `tiny` figure.
[ -f "$OUT/rooms/evaluation_index.json" ] || $UPLVSM make-dataset --config configs/tiny.json --out "$OUT/rooms"
# Nested subsets up to 8000 rooms (issue 72 and 83), each subset the first rooms of the next.
if wants scaling scaling-exact scaling-noise scaling-budget scaling-short sfm sfm-data sfm-exact sfm-noise all; then
  [ -f "$OUT/rooms_8000/evaluation_index.json" ] || $UPLVSM make-dataset --config configs/tiny.json \
    --train-scenes 8000 --out "$OUT/rooms_8000"
fi

if wants shuffle all; then
  # Issue 64 item 7: chunk pairs (ours) against one shuffle over the whole split (official), UP-LVSM, same budget.
  for per in 2 0; do
    grid "shuffle_chunks$per" scaling --config configs/tiny.json --data "$OUT/rooms" --subsets full --steps 4000 \
      "${COMMON[@]}" --set training.chunks_per_shuffle=$per
  done
fi

if wants pose-noise all; then
  # Both readings of the paper's levels: sd (the official noise_scale) 0.001 / 0.01 / 0.1 and variance 0.001 /
  # 0.01 / 0.1 (sd 0.0316 / 0.1 / 0.316).
  grid pose_noise pose-noise --config configs/tiny.json configs/tiny_lvsm.json --data "$OUT/rooms" \
    --noise-std 0 0.001 0.01 0.1 --noise-variance 0.001 0.01 0.1 --steps "$STEPS" "${COMMON[@]}"
fi

if wants scaling scaling-exact scaling-noise all; then
  # Issue 72: nested subsets 4x apart up to 8000 rooms, every run the same fixed budget (SCALE_STEPS, the largest
  # subset's need: every smaller subset then gets more epochs, so no run is limited by its steps) and held-out PSNR
  # every 500 steps to show each curve levelling off. scaling-exact and scaling-noise split the work between the two
  # cores. The second seed where the verdict needs it: SEEDS=778 SUBSETS="125 8000".
  read -r -a SUBSETS <<<"${SUBSETS:-125 500 2000 8000}"
  SCALE=(--data "$OUT/rooms_8000" --subsets "${SUBSETS[@]}" --steps "$SCALE_STEPS" --threads "$THREADS"
    --seeds "${SEEDS[@]}" --set training.eval_every=500 --set training.checkpoint_every=500)
  if ! wants scaling-noise; then
    grid scaling scaling --config configs/tiny.json configs/tiny_ptlvsm.json configs/tiny_lvsm.json "${SCALE[@]}"
  fi
  if ! wants scaling-exact; then
    # The posed models again with pose noise on their cameras (UP-LVSM never reads them). NOISE_CONFIGS picks the
    # models (a second seed).
    read -r -a NOISE_CONFIGS <<<"${NOISE_CONFIGS:-configs/tiny_ptlvsm.json configs/tiny_lvsm.json}"
    grid scaling_noise0.1 scaling --config "${NOISE_CONFIGS[@]}" "${SCALE[@]}" --noise-std 0.1
  fi
fi

if wants scaling-budget all; then
  # Issue 72: is SCALE_STEPS enough? The end subsets at twice the budget (a cosine schedule always flattens at its
  # end, so a flat tail alone does not prove it), which gives the gain per 4x again at that budget. UP-LVSM (said to
  # need steps before data pays) and LVSM (whose 8000-step curves still rose at their end).
  read -r -a BUDGET_CONFIGS <<<"${BUDGET_CONFIGS:-configs/tiny.json configs/tiny_lvsm.json}"
  read -r -a BUDGET_SUBSETS <<<"${BUDGET_SUBSETS:-125 8000}"
  grid "scaling_budget$((2 * SCALE_STEPS))" scaling --config "${BUDGET_CONFIGS[@]}" --data "$OUT/rooms_8000" \
    --subsets "${BUDGET_SUBSETS[@]}" --steps $((2 * SCALE_STEPS)) --threads "$THREADS" --seeds "${SEEDS[@]}" \
    --set training.eval_every=500 --set training.checkpoint_every=500
fi

if wants scaling-short && [ -n "${FROM_DOCS:-}" ]; then
  # Issue 72's first study (600 / 1200 / 2400 steps on 125 / 500 / 2000 rooms: 38 / 19 / 10 epochs), its committed
  # tables redrawn; it trained on rooms_2000, whose rooms are the first 2000 of rooms_8000.
  SHORT=(--data "$OUT/rooms_8000" --subsets 125 500 2000 --steps 600 --steps-growth 2 --seeds "${SEEDS[@]}")
  grid scaling_short scaling --config configs/tiny.json configs/tiny_ptlvsm.json configs/tiny_lvsm.json "${SHORT[@]}"
  grid scaling_short_noise0.1 scaling --config configs/tiny_ptlvsm.json configs/tiny_lvsm.json "${SHORT[@]}" \
    --noise-std 0.1
fi

if wants sfm sfm-data sfm-exact sfm-noise; then
  # Issue 83: rooms_8000's training rooms (linked, not rendered again) with TEST_ROOMS test rooms; the generator draws
  # each room from its split and index, so these test rooms begin with the 48 of every earlier figure.
  TEST_ROOMS=${TEST_ROOMS:-1024}
  SFM_DATA="$OUT/rooms_8000_test$TEST_ROOMS"
  if [ ! -f "$SFM_DATA/evaluation_index.json" ]; then
    rm -rf "$SFM_DATA.partial"
    $UPLVSM make-dataset --config configs/tiny.json --train-scenes 0 --test-scenes "$TEST_ROOMS" \
      --out "$SFM_DATA.partial"
    rm -rf "$SFM_DATA.partial/train" && ln -s "$(cd "$OUT/rooms_8000" && pwd)/train" "$SFM_DATA.partial/train"
    mv "$SFM_DATA.partial" "$SFM_DATA"
  fi
fi

if wants sfm sfm-exact sfm-noise; then
  SFM_SIGMA=${SFM_SIGMA:-0.01}
  read -r -a SEEDS <<<"${SEEDS_GIVEN:-777 778 779}"  # the design's seeds (REPORT_ONLY: runs not done read "(not run)")
  read -r -a SUBSETS <<<"${SUBSETS:-32 125 2000 8000}"
  SFM=(--data "$SFM_DATA" --subsets "${SUBSETS[@]}" --steps "$SCALE_STEPS" --threads "$THREADS" --seeds "${SEEDS[@]}"
    --set training.eval_every=500 --set training.checkpoint_every=500)
  if ! wants sfm-noise; then
    read -r -a SFM_EXACT_CONFIGS <<<"${SFM_EXACT_CONFIGS:-configs/tiny.json configs/tiny_lvsm.json configs/tiny_ptlvsm.json}"
    grid sfm_exact scaling --config "${SFM_EXACT_CONFIGS[@]}" "${SFM[@]}"
  fi
  if ! wants sfm-exact; then
    read -r -a SFM_NOISE_CONFIGS <<<"${SFM_NOISE_CONFIGS:-configs/tiny_lvsm.json configs/tiny_ptlvsm.json}"
    grid "sfm_noise$SFM_SIGMA" scaling --config "${SFM_NOISE_CONFIGS[@]}" "${SFM[@]}" --noise-std "$SFM_SIGMA"
  fi
fi
