#!/usr/bin/env bash
# Cost per particle-substep as the particle count grows 8x, 64x and 296x (the
# reference jelly cube at dx 0.02, 0.01, 0.005, 0.003: 27k, 216k, 1.73M, 8M
# particles),
# on 1 and 2 threads, median of N runs (default 3), about 50 substeps each.
#   bench/run_scaling.sh [runs]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
bin=build/bench/bench_mpm
[ -x "$bin" ] || scripts/build.sh release bench_mpm >/dev/null
tmp=$(mktemp -d)
export OMP_WAIT_POLICY=passive
printf "| dx | particles | threads | ns per particle-substep (median of %s) | particle-substeps/s | bytes/particle held |\n|---|---|---|---|---|---|\n" "$runs"
for spec in "0.02 0.028" "0.01 0.014" "0.005 0.007" "0.003 0.0042"; do
  read -r dx time <<<"$spec"
  sed -E "s/\"dx\": 0.01/\"dx\": $dx/; s/jelly_cube_216k/jelly_cube_dx$dx/" bench/scenes/jelly_cube_216k.json > "$tmp/s.json"
  for threads in 1 2; do
    rates=(); held=""; n=""
    for ((r = 0; r < runs; r++)); do
      line=$($bin "$tmp/s.json" --time "$time" --threads "$threads")
      echo "$line" >&2
      rates+=("$(sed -E 's/.*particle_substeps_per_s=([^ ]+).*/\1/' <<<"$line")")
      held=$(sed -E 's/.*bytes_per_particle_held=([^ ]+).*/\1/' <<<"$line")
      n=$(sed -E 's/.*particles=([^ ]+).*/\1/' <<<"$line")
    done
    median=$(printf "%s\n" "${rates[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
    awk -v dx="$dx" -v n="$n" -v t="$threads" -v r="$median" -v h="$held" \
      'BEGIN { printf "| %s | %s | %s | %.0f | %.3g | %s |\n", dx, n, t, 1e9 / r, r, h }'
  done
done
rm -rf "$tmp"
