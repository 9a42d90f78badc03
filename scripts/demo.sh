#!/usr/bin/env bash
# README command (a): install what is missing, build, and run the default scene.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh release triad
scene=${1:-scenes/default.json}
./build/app/triad run "$scene"
