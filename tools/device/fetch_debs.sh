#!/usr/bin/env bash
# Downloads (never installs) the Debian bookworm packages a GPU machine without them needs to build uplvsm against
# its own CUDA LibTorch: headers, CMake/pkg-config files and the shared libraries they point at, as .debs in
# .devdeps/ (git-ignored), which tools/device/gpu_session.sh unpacks into /tmp/deps there. FFmpeg is left out (its
# codec libraries come to ~150 MB): that build configures with -DUPLVSM_WITH_FFMPEG=OFF.
# Usage, from the repository root on a Debian 12 machine: bash tools/device/fetch_debs.sh
set -euo pipefail
mkdir -p .devdeps
grep -qs '^/.devdeps/$' .git/info/exclude || { mkdir -p .git/info && echo '/.devdeps/' >>.git/info/exclude; }
cd .devdeps
chmod 777 .  # apt's download user must be able to write here
apt-get download \
  nlohmann-json3-dev libcli11-dev libspdlog-dev libspdlog1.10 libfmt-dev libfmt9 \
  libjpeg62-turbo-dev libjpeg62-turbo libpng-dev libpng16-16 zlib1g-dev zlib1g \
  libexif-dev libexif12 libcpp-httplib-dev libcpp-httplib0.11 libssl-dev libssl3 libbrotli-dev libbrotli1 \
  libgtest-dev libgmock-dev libbenchmark-dev libbenchmark1debian \
  pkgconf pkgconf-bin libpkgconf3
ls -1 | wc -l
