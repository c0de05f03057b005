#!/usr/bin/env bash
# Builds the libFuzzer targets with clang + ASan/UBSan in build-fuzz/ and runs each for a short while,
# seeded from data/, the hostile corpus (fuzz/hostile_corpus.h) and ../shared/data when present; then, given the test binary, runs its command-line
# tests (Cli.*) against the sanitizer build of clusterbake. Usage: fuzz-smoke.sh [RUNS_PER_TARGET [CB_TESTS]]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3000}
cli_tests=${2:-}
cmake -S . -B build-fuzz -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCLUSTERBAKE_FUZZ=ON -DCLUSTERBAKE_TESTS=OFF -DCLUSTERBAKE_BENCH=OFF >/dev/null
cmake --build build-fuzz --target fuzz_gltf fuzz_obj fuzz_off fuzz_ply fuzz_stl fuzz_asset make_hostile_corpus clusterbake
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
seed() {  # seed FORMAT FILE...
  mkdir -p "$work/$1"
  for f in "${@:2}"; do [ -f "$f" ] && cp "$f" "$work/$1/" || true; done
}
shared=../shared/data
seed gltf data/small/*.gltf data/small/*.glb $shared/gltf/Box_Draco.glb $shared/gltf/BoxDraco/BoxDraco.gltf $shared/gltf/nested.glb
seed obj data/small/*.obj $shared/hard/deg_faces.obj $shared/hard/wallhole.obj $shared/hard/negative_indices.obj
seed off data/small/*.off $shared/hard/comments.off $shared/hard/whitespace.off
seed ply data/small/*.ply
seed stl data/small/*.stl $shared/hard/soup.stl
./build-fuzz/fuzz/make_hostile_corpus "$work/hostile" >/dev/null  # declared sizes, hierarchies, escapes
seed gltf "$work"/hostile/corpus/gltf/*.gltf "$work"/hostile/corpus/gltf/*.glb
seed obj "$work"/hostile/corpus/mesh/*.obj
seed off "$work"/hostile/corpus/mesh/*.off
seed ply "$work"/hostile/corpus/mesh/*.ply
seed stl "$work"/hostile/corpus/mesh/*.stl
mkdir -p "$work/asset"  # assets baked here, with and without bounds, by the instrumented tool itself
./build-fuzz/cli/clusterbake bake data/small/cube.obj --bounds all -o "$work/asset/cube_all.cbk" >/dev/null
./build-fuzz/cli/clusterbake cluster data/small/primitive_modes.gltf -o "$work/asset/modes.cbk" >/dev/null
./build-fuzz/cli/clusterbake bake data/small/cube_binary.stl --fine 4 --coarse 8 -o "$work/asset/cube_small.cbk" >/dev/null
for format in gltf obj off ply stl asset; do
  echo "fuzz_$format: $runs runs from $(ls "$work/$format" | wc -l) seeds"
  ./build-fuzz/fuzz/fuzz_$format -runs="$runs" -max_len=65536 -rss_limit_mb=2048 -timeout=20 \
    -print_final_stats=0 -artifact_prefix=build-fuzz/artifact- "$work/$format" 2>"$work/$format.log" || { tail -40 "$work/$format.log"; exit 1; }
  grep -E "^#[0-9]+ *DONE" "$work/$format.log" || tail -2 "$work/$format.log"
done
echo "fuzz smoke: 6 targets, no crash"
if [ -n "$cli_tests" ]; then
  echo "command-line tests against the AddressSanitizer + UBSan build of clusterbake:"
  CB_CLI_UNDER_TEST=$PWD/build-fuzz/cli/clusterbake "$cli_tests" --gtest_filter='Cli.*' --gtest_brief=1
fi
