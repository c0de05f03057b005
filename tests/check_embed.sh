#!/usr/bin/env bash
# Installs the build into a fresh prefix, builds examples/embed against that prefix alone, and checks that
# its shadow answers on the default scene are those of `clusterbake query`. Usage: check_embed.sh BUILD_DIR
set -euo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)
# docs/RUNTIME.md's embedding example is word for word a function of examples/embed/main.cpp, compiled below.
doc_example() { awk '/^    \/\/ bytes: the asset in memory/ { on = 1 } on { print substr($0, 5) } on && /^    }$/ { exit }' "$1"; }
code_example() { awk '/^\/\/ bytes: the asset in memory/ { on = 1 } on { print } on && /^}$/ { exit }' "$1"; }
if ! diff <(doc_example "$src/docs/RUNTIME.md") <(code_example "$src/examples/embed/main.cpp"); then
  echo "docs/RUNTIME.md's embedding example differs from examples/embed/main.cpp"
  exit 1
fi
[ "$(code_example "$src/examples/embed/main.cpp" | wc -l)" -gt 10 ] || { echo "no embedding example found"; exit 1; }
build=$(cd "$1" && pwd)
work=$build/embed_check
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" >/dev/null
cmake -S "$src/examples/embed" -B "$work/build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/build" >/dev/null
tool=$work/prefix/bin/clusterbake
"$tool" bake "$src/data/default_scene.glb" -o "$work/scene.cbk" >/dev/null
# A grid of points just above the ground, under and around the scene's objects.
awk 'BEGIN { for (i = 0; i < 80; ++i) for (j = 0; j < 80; ++j) printf "%g 0.05 %g\n", -20 + 0.5 * i, -20 + 0.5 * j }' >"$work/points.txt"
"$tool" query "$work/scene.cbk" --light -4,30,2 --points "$work/points.txt" >"$work/query.txt"
"$work/build/embed" "$work/scene.cbk" -4,30,2 "$work/points.txt" >"$work/embed.txt"
cmp "$work/query.txt" "$work/embed.txt"
points=$(wc -l <"$work/embed.txt")
shadowed=$(grep -c '^1$' "$work/embed.txt" || true)
echo "embed: $points points, $shadowed in shadow: the same answers as clusterbake query"
[ "$shadowed" -gt 0 ] && [ "$shadowed" -lt "$points" ]
