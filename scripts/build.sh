#!/usr/bin/env bash
# Configures and builds Triad. Usage: scripts/build.sh [release|sanitize] [targets...]
#   release  (default) optimised build in build/
#   sanitize ASan + UBSan build in build-sanitize/
set -euo pipefail
cd "$(dirname "$0")/.."
kind=${1:-release}
shift || true
case "$kind" in
  release) dir=build; flags=(-DCMAKE_BUILD_TYPE=Release) ;;
  # Line tables only (-g1): the sanitizers' reports keep file and line, and
  # the build is a quarter to a third faster than with full debug
  # information (app/check_scene.cpp: 15-21 s against 23-27 s).
  # Clang compiles it in 57% of GCC's time (398 s against 699 s for the
  # unit tests on the 2-core machine, most of CI's sanitizer stage), and
  # the fuzzers need it anyway; TRIAD_SANITIZE_CXX=g++ picks GCC.
  sanitize) dir=build-sanitize
    cxx=${TRIAD_SANITIZE_CXX:-clang++}
    flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" -DTRIAD_SANITIZE=ON
           "-DCMAKE_CXX_COMPILER=$cxx")
    # A build folder made with another compiler is configured afresh.
    if [ -f "$dir/CMakeCache.txt" ] &&
       ! grep -q "^CMAKE_CXX_COMPILER:[A-Z]*=.*$(basename "$cxx")\$" "$dir/CMakeCache.txt"; then
      rm -rf "$dir/CMakeCache.txt" "$dir/CMakeFiles"
    fi ;;
  *) echo "usage: $0 [release|sanitize] [targets...]" >&2; exit 2 ;;
esac
# TRIAD_BENCH=OFF leaves out bench/ (the test script: no test runs them).
cmake -S . -B "$dir" -G Ninja "${flags[@]}" -DTRIAD_BENCH="${TRIAD_BENCH:-ON}" >/dev/null
jobs=$(nproc)
if [ $# -gt 0 ]; then
  cmake --build "$dir" -j "$jobs" --target "$@"
else
  cmake --build "$dir" -j "$jobs"
fi
