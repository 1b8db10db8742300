#!/usr/bin/env bash
# Installs the Debian bookworm packages vdb_isosimp needs to build and test. Idempotent; needs root
# (or sudo) only when something is missing.
set -euo pipefail
PKGS=(build-essential cmake pkg-config
      libopenvdb-dev libboost-iostreams-dev libtbb-dev libopenmesh-dev libcli11-dev
      libgtest-dev libgmock-dev zlib1g-dev libdcmtk-dev libtiff-dev time
      libmeshoptimizer-dev python3-vtk9
      libtinygltf-dev pybind11-dev libboost-python-dev python3-dev python3-numpy python3-openvdb blender
      clang libclang-rt-14-dev openmpi-bin libopenmpi-dev)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "installing: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
