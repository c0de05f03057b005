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
  libmeshoptimizer-dev       # EXT_meshopt_compression's decoders (io/), and a peer in the benchmarks
  libembree-dev
  zlib1g-dev                 # PNG heat maps (clusterbake heatmap, report --heatmap)
  libpng-dev chromium chromium-driver   # the report's browser test: headless Chromium renders report.html
  clang libclang-rt-14-dev   # libFuzzer + AddressSanitizer for the fuzz targets
  clang-format               # the format test (scripts/check-format.sh)
  assimp-testmodels          # real broken and Draco glTF files the tests read in place
  nodejs                     # the tests' npm packages: the glTF validator, gltfpack, glTF-Transform
  pybind11-dev python3-dev python3-pybind11 python3-numpy python3-pytest   # the Python module and its tests
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

# The npm packages the tests run, their versions pinned by tests/node/package-lock.json: the Khronos glTF
# validator (on export-gltf's outputs), gltfpack and glTF-Transform's command line (whose outputs the loader
# tests read). Into tests/node/node_modules, which git ignores; skipped when those versions are there already.
node_dir="$(cd "$(dirname "$0")/.." && pwd)/tests/node"
npm_packages="['gltf-validator', 'gltfpack', '@gltf-transform/cli']"
want=$(cd "$node_dir" && node -p "const l = require('./package-lock.json').packages;
  ${npm_packages}.map(n => n + '@' + l['node_modules/' + n].version).join(' ')")
have=$(cd "$node_dir" && node -p "${npm_packages}.map(n => { try { return n + '@' +
  require('./node_modules/' + n + '/package.json').version; } catch (e) { return n + '@none'; } }).join(' ')")
if [ "$have" = "$want" ]; then
  echo "install-deps: npm packages present: $want"
else
  echo "install-deps: installing $want with npm"
  (cd "$node_dir" && npm ci --no-audit --no-fund --loglevel=error)
fi
