#!/usr/bin/env bash
# Validation suite (issue 7): accuracy against cost.
# Usage: bench/validation/run.sh [--quick] [--threads N] [--cases a,b] [--check-only] [--no-check]
#        [--no-experiments]
# Installs what is missing (scripts/setup.sh --validation), builds triad if
# needed, runs every validation scene over its sweep (dx, particles_per_cell,
# cfl, transfer), compares with analytic solutions and published
# experiments, then runs every case at each --quality preset, and writes
# bench/validation/results/{runs.csv, presets.csv, summary.md, CASE.png,
# machine.json}. Exit status 1 when an analytic case misses its tolerance at
# `--quality final`. Then (unless --no-experiments) the experiments across
# their parameter (experiments.py: the granular collapse at five aspect
# ratios, planar and axisymmetric, at two dx; the dam-break front at every
# dx), into collapse_aspect.{csv,png}, dam_break_front.{csv,png} and
# experiments.md (with --quick: the base dx only).
set -euo pipefail
cd "$(dirname "$0")/../.."
export OMP_WAIT_POLICY=passive
# Debian's python3 with numpy and matplotlib, and the build's packages.
scripts/setup.sh --validation
[ -x build/app/triad ] || scripts/build.sh release triad
experiments=1
args=()
for a in "$@"; do
  if [ "$a" = --no-experiments ]; then experiments=0; else args+=("$a"); fi
done
status=0
/usr/bin/python3 bench/validation/validate.py "${args[@]}" || status=$?
if [ "$experiments" = 1 ]; then
  # The flags both scripts take: --quick and --threads N.
  extra=()
  prev=
  for a in "${args[@]}"; do
    case "$a" in --quick) extra+=(--quick) ;; esac
    [ "$prev" = --threads ] && extra+=(--threads "$a")
    prev=$a
  done
  /usr/bin/python3 bench/validation/experiments.py "${extra[@]}" || status=$?
fi
exit "$status"
