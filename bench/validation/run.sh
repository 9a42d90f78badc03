#!/usr/bin/env bash
# Validation suite (issue 7): accuracy against cost.
# Usage: bench/validation/run.sh [--quick] [--threads N] [--cases a,b] [--check-only] [--no-check]
# Installs what is missing (scripts/setup.sh --validation), builds triad if
# needed, runs every validation scene over its sweep (dx, particles_per_cell,
# cfl, transfer), compares with analytic solutions and published
# experiments, then runs every case at each --quality preset, and writes
# bench/validation/results/{runs.csv, presets.csv, summary.md, CASE.png,
# machine.json}. Exit status 1 when an analytic case misses its tolerance at
# `--quality final`. The whole run took 11 minutes on the 2-core CI machine.
set -euo pipefail
cd "$(dirname "$0")/../.."
export OMP_WAIT_POLICY=passive
# Debian's python3 with numpy and matplotlib, and the build's packages.
scripts/setup.sh --validation
[ -x build/app/triad ] || scripts/build.sh release triad
exec /usr/bin/python3 bench/validation/validate.py "$@"
