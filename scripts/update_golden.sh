#!/usr/bin/env bash
# Regenerates the golden preview images in tests/golden/ from the current
# solver and renderer, then checks them. Review the new images (and the
# `git diff --stat tests/golden`) before committing them.
# Usage: scripts/update_golden.sh            (Release build in build/)
#        BUILD_DIR=/tmp/b scripts/update_golden.sh
set -euo pipefail
cd "$(dirname "$0")/.."
build=${BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j "$(nproc)" --target triad triad_e2e_tests
TRIAD_UPDATE_GOLDEN=1 "$build/tests/triad_e2e_tests" --gtest_filter='Golden.*'
# The references must now pass, and the metric must still catch a moved block.
"$build/tests/triad_e2e_tests" --gtest_filter='Golden*:RenderCommand.*'
git status --short tests/golden || true
