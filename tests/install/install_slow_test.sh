#!/usr/bin/env bash
# The installed tree as a user gets it: `cmake --install` into a temporary prefix, every installed uplvsm header's
# uplvsm includes installed too, the installed binary runs, examples/render_two_photos builds against the prefix
# with find_package(uplvsm) and renders two photos to an MP4, and the installed Python package does the same.
#   install_slow_test.sh BUILD_DIR SOURCE_DIR FIXTURES PYTHON PYTHON_INSTALL_DIR
set -euo pipefail
build=$1 source=$2 fixtures=$3 python=$4 pydir=$5
# The photos and the checkpoint come from the reference fixture pack: without it, skip (exit 77), or fail under CI.
if [ ! -d "$fixtures" ]; then
  echo "reference fixture pack not found: $fixtures (configure with -DUPLVSM_FIXTURES=DIR; what it holds and how it" \
       "is made: docs/development.md, \"The reference fixture pack\")"
  if [ "${CI:-}" = true ] || [ "${CI:-}" = 1 ] || [ "${UPLVSM_REQUIRE_FIXTURES:-}" = 1 ]; then exit 1; fi
  exit 77
fi
work=$build/install_test  # a fixed path, so ccache reuses the example's object on later runs
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix

cmake --install "$build" --prefix "$prefix" > "$work/install.log"
for dir in bin/uplvsm lib/libuplvsm.so include/uplvsm/uplvsm.h lib/cmake/uplvsm/uplvsmConfig.cmake \
           share/uplvsm/configs/tiny.json "$pydir/uplvsm/__init__.py"; do
  test -e "$prefix/$dir" || { echo "not installed: $dir"; exit 1; }
done
# Public headers only include uplvsm headers that are installed as well.
missing=$(grep -rhoE '#include "uplvsm/[^"]+"' "$prefix/include/uplvsm" | sed -E 's/.*"(uplvsm\/[^"]+)"/\1/' | sort -u |
          while read -r h; do test -f "$prefix/include/$h" || echo "$h"; done)
test -z "$missing" || { echo "installed headers include headers that are not installed: $missing"; exit 1; }
# Internals stay private.
for private in cli/commands.h train/trainer.h core/pch.h kernels/flash_attention.h kernels/ops.h; do
  test ! -e "$prefix/include/uplvsm/$private" || { echo "private header installed: $private"; exit 1; }
done

# The installed binary finds libuplvsm.so through its $ORIGIN RPATH (and OpenBLAS through DT_RPATH).
"$prefix/bin/uplvsm" info > "$work/info.txt"
# A LibTorch that loads no shared BLAS (PyPI's has MKL built in) has no OpenBLAS to find.
if ! grep -q "^BLAS  *unknown BLAS (unknown)" "$work/info.txt"; then
  grep -q "openblas" "$work/info.txt" ||
    { echo "installed uplvsm does not use OpenBLAS:"; cat "$work/info.txt"; exit 1; }
fi

# Two photos: frames 1 and 13 of a RealEstate10K-like fixture scene, as PNG files (the LVSM layout).
"$prefix/bin/uplvsm" dataset convert --from chunks --input "$fixtures/re10k_chunks/root/test" --output "$work/lvsm" \
  > "$work/convert.log" 2>&1 || { cat "$work/convert.log"; exit 1; }
photo_a=$work/lvsm/images/20e408dd375292a1/00001.png photo_b=$work/lvsm/images/20e408dd375292a1/00013.png
checkpoint=$fixtures/official_uplvsm/checkpoint.pt

check_mp4() {  # an MP4 file: an 'ftyp' box first, and more than a header's worth of bytes
  test "$(head -c 8 "$1" | tail -c 4)" = "ftyp" || { echo "$1 is not an MP4"; exit 1; }
  test "$(stat -c %s "$1")" -gt 2000 || { echo "$1 is too small"; exit 1; }
}

launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S "$source/examples/render_two_photos" -B "$work/example" -DCMAKE_PREFIX_PATH="$prefix" "${launcher[@]}" \
  > "$work/example_configure.log"
cmake --build "$work/example" > "$work/example_build.log"
"$work/example/render_two_photos" "$checkpoint" "$photo_a" "$photo_b" "$work/cpp.mp4" | tee "$work/cpp.txt"
grep -q "wrote 24 frames" "$work/cpp.txt"
check_mp4 "$work/cpp.mp4"

PYTHONPATH=$prefix/$pydir PYTHONDONTWRITEBYTECODE=1 "$python" -c \
  "import sys, uplvsm; sys.exit(0 if uplvsm.__file__.startswith('$prefix/') else 'imported ' + uplvsm.__file__)"
PYTHONPATH=$prefix/$pydir PYTHONDONTWRITEBYTECODE=1 "$python" "$source/examples/render_two_photos/render_two_photos.py" \
  "$checkpoint" "$photo_a" "$photo_b" "$work/python.mp4" | tee "$work/python.txt"
grep -q "wrote 24 frames" "$work/python.txt"
check_mp4 "$work/python.mp4"
echo "install test passed"
