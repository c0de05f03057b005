#!/usr/bin/env bash
# Installs the build into a fresh prefix, builds examples/embed against that prefix alone, and checks that
# its shadow answers are those of `clusterbake query`: embed's on the default scene, embed_level's on a
# level of the default scene and a cube moved between two frames. Usage: check_embed.sh BUILD_DIR
set -euo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)
# docs/RUNTIME.md's two examples are word for word functions of examples/embed, compiled below: each starts
# at a comment line given here and ends at the function's closing brace.
doc_example() { awk -v first="    // $2" 'index($0, first) == 1 { on = 1 } on { print substr($0, 5) } on && /^    }$/ { exit }' "$1"; }
code_example() { awk -v first="// $2" 'index($0, first) == 1 { on = 1 } on { print } on && /^}$/ { exit }' "$1"; }
for example in "main.cpp:bytes: the asset in memory" "level.cpp:ground, prop: opened assets"; do
  file=${example%%:*} first=${example#*:}
  if ! diff <(doc_example "$src/docs/RUNTIME.md" "$first") <(code_example "$src/examples/embed/$file" "$first"); then
    echo "docs/RUNTIME.md's example differs from examples/embed/$file"
    exit 1
  fi
  [ "$(code_example "$src/examples/embed/$file" "$first" | wc -l)" -gt 10 ] || { echo "no example in $file"; exit 1; }
done
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
{ [ "$shadowed" -gt 0 ] && [ "$shadowed" -lt "$points" ]; } || { echo "embed: no shadow, or nothing lit"; exit 1; }

# A level: the default scene as baked and a cube (three times its size) moved between two frames, the same
# matrices as examples/embed/level.cpp's, as level files for clusterbake query.
"$tool" bake "$src/data/small/cube.obj" -o "$work/cube.cbk" >/dev/null
echo '{"instances": [{"asset": "scene.cbk"}, {"asset": "cube.cbk", "matrix": [3,0,0,0, 0,3,0,0, 0,0,3,0, 8,6,8,1]}]}' >"$work/frame1.json"
echo '{"instances": [{"asset": "scene.cbk"}, {"asset": "cube.cbk", "matrix": [0,0,3,0, 0,3,0,0, 3,0,0,0, -10,5,-6,1]}]}' >"$work/frame2.json"
cat <("$tool" query "$work/frame1.json" --light -4,30,2 --points "$work/points.txt") \
    <("$tool" query "$work/frame2.json" --light -4,30,2 --points "$work/points.txt") >"$work/level_query.txt"
"$work/build/embed_level" "$work/scene.cbk" "$work/cube.cbk" -4,30,2 "$work/points.txt" >"$work/level_embed.txt"
cmp "$work/level_query.txt" "$work/level_embed.txt"
frame1=$(head -n "$points" "$work/level_embed.txt" | grep -c '^1$' || true)
frame2=$(tail -n "$points" "$work/level_embed.txt" | grep -c '^1$' || true)
moved=$(paste -d' ' <(head -n "$points" "$work/level_embed.txt") <(tail -n "$points" "$work/level_embed.txt") | grep -c '^0 1$\|^1 0$' || true)
echo "embed_level: $points points, $frame1 then $frame2 in shadow, $moved answers changed by the move: the same as clusterbake query"
{ [ "$frame1" -gt "$shadowed" ] && [ "$moved" -gt 0 ]; } || { echo "embed_level: the cube casts no shadow, or its move changes none"; exit 1; }
