#!/usr/bin/env bash
# Installs everything clusterbake builds, tests and benchmarks with, from Debian's packages only.
set -euo pipefail
packages=(
  cmake ninja-build g++ ccache pkg-config
  libcgal-dev libeigen3-dev libopenmesh-dev libdraco-dev libtinygltf-dev libflann-dev
  nlohmann-json3-dev libcli11-dev libgtest-dev
  libxxhash-dev              # input hashes of incremental batch bakes
  python3-distributed        # scripts/clusterbake-dask and its test (Dask scheduler and workers)
  qemu-user                  # the portability test runs the binary as older processors
  libmeshoptimizer-dev libembree-dev
  zlib1g-dev                 # PNG heat maps (clusterbake heatmap, report --heatmap)
  libpng-dev chromium chromium-driver   # the report's browser test: headless Chromium renders report.html
  clang libclang-rt-14-dev   # libFuzzer + AddressSanitizer for the fuzz targets
  clang-format               # the format test (scripts/check-format.sh)
  assimp-testmodels          # real broken and Draco glTF files the tests read in place
  nodejs                     # the Khronos glTF validator, run on export-gltf's outputs by the tests
)
# Some builds of nodejs bring npm themselves and conflict with Debian's npm package: ask for it only when
# there is no npm.
command -v npm >/dev/null 2>&1 || packages+=(npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
else
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "install-deps: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The glTF validator (an npm package, its version pinned by tests/node/package-lock.json) into
# tests/node/node_modules, which git ignores; skipped when that version is there already.
node_dir="$(cd "$(dirname "$0")/.." && pwd)/tests/node"
want=$(cd "$node_dir" && node -p "require('./package-lock.json').packages['node_modules/gltf-validator'].version")
have=$(cd "$node_dir" && node -p "require('./node_modules/gltf-validator/package.json').version" 2>/dev/null || true)
if [ "$have" = "$want" ]; then
  echo "install-deps: gltf-validator $want present"
else
  echo "install-deps: installing gltf-validator $want with npm"
  (cd "$node_dir" && npm ci --no-audit --no-fund --loglevel=error)
fi
