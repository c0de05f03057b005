#!/usr/bin/env bash
# export-gltf's GLBs through the Khronos glTF validator: SCENE baked with every bounding volume, exported with
# its boxes and cones, with its spheres and capsules too, and at the coarse level; the validator may report
# informations and hints but no error and no warning.
# Usage: check_gltf_export.sh CLUSTERBAKE NODE SCENE WORKDIR
# Exits 77, which ctest counts as skipped, when SCENE is absent (a shared scene, in a clone without them).
set -euo pipefail
cli=$1 node=$2 scene=$3 work=$4
here=$(cd "$(dirname "$0")" && pwd)
if [ ! -f "$scene" ]; then
  echo "skipped: $scene is absent (no shared scenes beside the checkout)"
  exit 77
fi
mkdir -p "$work"
name=$(basename "$scene")
name=${name%.*}
"$cli" bake "$scene" --bounds all -o "$work/$name.cbk" -q >/dev/null
"$cli" export-gltf "$work/$name.cbk" --boxes --cones -o "$work/$name.fine.glb"
"$cli" export-gltf "$work/$name.cbk" --boxes=obb,sphere,capsule -o "$work/$name.volumes.glb"
"$cli" export-gltf "$work/$name.cbk" --level coarse --boxes --cones -o "$work/$name.coarse.glb"
"$node" "$here/node/validate_gltf.mjs" "$work/$name.fine.glb" "$work/$name.volumes.glb" "$work/$name.coarse.glb"
