#!/usr/bin/env bash
# Installs the Debian 12 packages Triad needs, only those that are missing.
# Runs as root, or through sudo when available.
#   scripts/setup.sh               what building and testing need
#   scripts/setup.sh --validation  also Python with NumPy and Matplotlib, for
#                                  bench/validation/run.sh
set -euo pipefail

PACKAGES=(
  # toolchain
  g++ cmake ninja-build pkg-config
  # sim/: linear algebra (OpenMP comes with g++)
  libeigen3-dev
  # import/, export/, app/: scene files, meshes, volumes, command line
  nlohmann-json3-dev libcli11-dev libassimp-dev
  libopenvdb-dev libboost-iostreams-dev libtbb-dev
  # render/: headless OpenGL and PNG
  libosmesa6-dev libpng-dev
  # dist/: one simulation over several processes (mpirun -np N triad run)
  libopenmpi-dev openmpi-bin
  # tests/ (vdb_print reads the VDB caches back independently; assimp-testmodels
  # holds real-world and broken meshes for the import tests)
  libgtest-dev libopenvdb-tools assimp-testmodels
  # scripts/fuzz.sh: libFuzzer with clang's sanitizers; the sanitizer build
  # (scripts/build.sh sanitize) is clang's too, with LLVM's OpenMP
  clang libclang-rt-14-dev libomp-dev
  # the suite's `validation` tests read the caches with numpy
  python3 python3-numpy
  # the suite's `client` tests open the caches with the programs users open
  # them with: VTK's readers, OpenVDB's Python module, Blender (headless).
  # Blender loads OpenGL at run time (libepoxy) and names none of it: its
  # Workbench render needs EGL and Mesa's software driver, surfaceless
  python3-vtk9 python3-openvdb blender libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri
)
if [ "${1:-}" = "--validation" ]; then
  # bench/validation/: the whole sweep also plots error against cost
  PACKAGES+=(python3-matplotlib)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "setup: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null; then SUDO="sudo"; else
    echo "setup: need root (or sudo) to install: ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done"
