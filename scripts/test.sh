#!/usr/bin/env bash
# README command (b): install what is missing, build, and run every test:
# the whole suite on the optimised build, then the fast unit tests again
# under AddressSanitizer and UndefinedBehaviorSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh release
(cd build && ctest --output-on-failure)
scripts/build.sh sanitize triad_unit_tests
(cd build-sanitize && ASAN_OPTIONS=detect_leaks=1 ctest --output-on-failure -L unit)
