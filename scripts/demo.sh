#!/usr/bin/env bash
# Installs dependencies, builds, and runs the main job on the shipped default scene: load, cluster and fit
# bounds (bake), validate.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
./build/cli/clusterbake info data/default_scene.glb
./build/cli/clusterbake bake data/default_scene.glb -o build/default_scene.cbk
./build/cli/clusterbake validate build/default_scene.cbk
