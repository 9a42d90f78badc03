#!/usr/bin/env bash
# Throughput and memory of the solver on the three reference scenes, at 1
# and 2 threads, median of N runs (default 3). Usage:
#   bench/run_mpm_bench.sh [runs] [sim_time]
# Prints one line per run and a median table for bench/RESULTS.md.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
time=${2:-0.1}
bin=build/bench/bench_mpm
[ -x "$bin" ] || scripts/build.sh release bench_mpm >/dev/null
printf "| scene | particles | threads | particle-substeps/s (median of %s) | peak bytes/particle (RSS growth) | bytes/particle held |\n|---|---|---|---|---|---|\n" "$runs" > /tmp/triad_bench_table.md
for scene in jelly_cube_216k sand_column_216k dam_break_216k; do
  for threads in 1 2; do
    rates=(); rss=""; held=""; n=""
    for ((r = 0; r < runs; r++)); do
      line=$($bin bench/scenes/$scene.json --time "$time" --threads "$threads")
      echo "$line" >&2
      rates+=("$(sed -E 's/.*particle_substeps_per_s=([^ ]+).*/\1/' <<<"$line")")
      rss=$(sed -E 's/.*bytes_per_particle_rss=([^ ]+).*/\1/' <<<"$line")
      held=$(sed -E 's/.*bytes_per_particle_held=([^ ]+).*/\1/' <<<"$line")
      n=$(sed -E 's/.*particles=([^ ]+).*/\1/' <<<"$line")
    done
    median=$(printf "%s\n" "${rates[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
    printf "| %s | %s | %s | %.3g | %s | %s |\n" "$scene" "$n" "$threads" "$median" "$rss" "$held" >> /tmp/triad_bench_table.md
  done
done
cat /tmp/triad_bench_table.md
