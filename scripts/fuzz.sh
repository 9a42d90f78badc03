#!/usr/bin/env bash
# Fuzzes the scene loader and the mesh importer with libFuzzer (clang, with
# AddressSanitizer and UndefinedBehaviorSanitizer) for SECONDS each
# (default 60), from the seed corpora in fuzz/corpus/ plus the repository's
# own scenes and meshes. A crash stops it with the input saved under
# build-fuzz/ (add it to fuzz/corpus/ once fixed: it stays a regression
# input). scripts/test.sh runs both targets; scripts/setup.sh installs
# clang.
#   scripts/fuzz.sh [SECONDS] [scene] [mesh]   (both targets when none named)
# An input slower than 30 s is a hang (the inputs take milliseconds; the
# margin is for a machine busy with other work).
# FUZZ_SEED=N fixes libFuzzer's seed: the same inputs in the same order on
# every machine, so that what passes here passes in CI (scripts/test.sh
# sets it; by hand, leave it unset to explore with a new seed each run).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(scene mesh)
out=build-fuzz
mkdir -p "$out/scene" "$out/mesh"
flags=(-std=c++17 -O1 -gline-tables-only -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -I. -I/usr/include/eigen3)
# The two targets compile side by side (CI's time is mostly compiling).
clang++ "${flags[@]}" fuzz/fuzz_scene.cpp import/scene_file.cpp import/scene_loader.cpp \
  import/param_dict.cpp -o "$out/fuzz_scene" &
scene_build=$!
clang++ "${flags[@]}" fuzz/fuzz_mesh.cpp import/mesh_loader.cpp import/mesh_precheck.cpp sim/shot/animation.cpp \
  -lassimp -o "$out/fuzz_mesh"
wait "$scene_build"
# Seeds: the corpora, every scene of the repository, its meshes (first
# byte: the format, as fuzz_mesh reads it).
cp fuzz/corpus/scene/* scenes/*.json bench/scenes/*.json "$out/scene/" 2>/dev/null || true
cp fuzz/corpus/mesh/* "$out/mesh/" 2>/dev/null || true
for m in scenes/meshes/*.obj; do { printf '\000'; cat "$m"; } > "$out/mesh/seed_$(basename "$m")"; done
# Small real-world and broken files of the other formats (assimp-testmodels).
models=/usr/share/assimp/models
k=1
for ext in stl ply gltf; do
  for m in $(find "$models" -iname "*.$ext" -size -20k 2>/dev/null | sort | head -12); do
    { printf "\\$(printf '%03o' $k)"; cat "$m"; } > "$out/mesh/seed_${ext}_$(basename "$m")"
  done
  k=$((k + 1))
done
export ASAN_OPTIONS=detect_leaks=0
# Each run writes crash-*, leak-* or timeout-* inputs into the build dir.
# The whole report is in build-fuzz/TARGET.log; on a failure its error part
# is printed. The targets run side by side, one core each.
pids=()
for t in "${targets[@]}"; do
  seed=()
  [ -n "${FUZZ_SEED:-}" ] && seed=(-seed="$FUZZ_SEED")
  (cd "$out" && exec "./fuzz_$t" "${seed[@]}" -max_total_time="$seconds" -timeout=30 -rss_limit_mb=2048 \
     -print_final_stats=1 "$t" > "$t.log" 2>&1) &
  pids+=($!)
done
failed=0
for k in "${!targets[@]}"; do
  t=${targets[$k]}
  if ! wait "${pids[$k]}"; then
    grep -A40 -m1 "ERROR\|assert" "$out/$t.log" | head -60
    tail -12 "$out/$t.log"
    failed=1
  else
    tail -6 "$out/$t.log"
  fi
done
exit "$failed"
