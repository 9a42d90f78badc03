#!/usr/bin/env bash
# Validation suite (issue 7): accuracy against cost.
# Usage: bench/validation/run.sh [--quick] [--threads N] [--cases a,b] [--check-only] [--no-check]
# Builds triad if needed, runs every validation scene over its sweep (dx,
# particles_per_cell, cfl, transfer), compares with analytic solutions and
# published experiments, and writes bench/validation/results/{runs.csv,
# summary.md, CASE.png, final_check.csv, machine.json}. Then runs the analytic
# cases at `--quality final` against their tolerances; exit status 1 when one
# misses. The full sweep takes about 35 minutes on the 2-core CI machine.
set -euo pipefail
cd "$(dirname "$0")/../.."
export OMP_WAIT_POLICY=passive
[ -x build/app/triad ] || scripts/build.sh release triad
# Debian's python3 has numpy and matplotlib (python3-numpy, python3-matplotlib).
exec /usr/bin/python3 bench/validation/validate.py "$@"
