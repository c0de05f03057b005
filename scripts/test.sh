#!/usr/bin/env bash
# Installs dependencies, builds, and runs every test (unit, real-data, CLI and fuzz smoke runs).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j "$(nproc)"
