#!/usr/bin/env bash
# Copies the part of the reference fixture pack that fits one device call (the call carries at most 64 MiB with the
# working tree) into .fixtures/ (git-ignored), which tools/device/gpu_session.sh uses as the pack: the metric,
# chunk-format, LVSM and official-forward fixtures (~28 MB); DINOv2, LPIPS and the training replay stay behind. The
# tests treat a pack as whole: those that need a part left behind fail there on the missing file (24 of them when
# official_uplvsm/ stays behind too, as on 2026-11-28), which is read as "not run", not as a regression.
# Usage, from the repository root: bash tools/device/pack_fixtures.sh [pack, default ../shared/fixtures]
set -euo pipefail
PACK=${1:-../shared/fixtures}
grep -qs '^/.fixtures/$' .git/info/exclude || { mkdir -p .git/info && echo '/.fixtures/' >>.git/info/exclude; }
rm -rf .fixtures && mkdir -p .fixtures
cp -r "$PACK"/README.md "$PACK"/ssim_psnr "$PACK"/re10k_chunks "$PACK"/lvsm "$PACK"/official_uplvsm .fixtures/
du -sh .fixtures
