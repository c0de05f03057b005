#!/usr/bin/env bash
# The default build runs on any x86-64 and gives the same answers on whatever lanes it picks.
#   1. No function of the binary outside the AVX2 and AVX-512 builds of the query body (cb::lanes_avx,
#      cb::lanes_avx512) and the bake's vector clones (base/vector_clones.h: GCC names their bodies
#      "[clone .avx2]" and "[clone .avx512f]", and picks one by the processor when the program loads) holds
#      an instruction beyond baseline x86-64: the linker kept no out-of-line copy of a shared function from
#      those builds.
#   2. Emulated as an older processor (qemu-user: Westmere, without AVX; qemu64, baseline x86-64 only), the
#      binary bakes the default scene byte for byte as natively and answers queries on SSE2 lanes with the
#      native answers. Emulated as Haswell (AVX2 without AVX-512), it bakes through the vector clones' AVX2
#      bodies, byte for byte as natively.
#   3. CLUSTERBAKE_LANES=sse2, avx2 and avx512 (those this processor runs) give the same answers, for a point
#      light and for a sun.
# Usage: check_portable.sh CLUSTERBAKE SOURCE_DIR WORK_DIR
set -euo pipefail
tool=$1
src=$2
work=$3
rm -rf "$work"
mkdir -p "$work"

# 1. Instructions beyond baseline x86-64: VEX/EVEX encoded (v...), AVX-512 mask registers (k...), wide
#    registers, and the scalar extensions (POPCNT, LZCNT, BMI). Not TZCNT: its encoding is REP BSF, which
#    compilers emit for baseline targets too, and which older processors run as BSF.
objdump -d -C --no-show-raw-insn "$tool" >"$work/disassembly.txt"
awk '
  /^[0-9a-f]+ <.*>:$/ { name = substr($0, index($0, "<") + 1); sub(/>:$/, "", name); next }
  /^ +[0-9a-f]+:\t/ {
    split($0, part, "\t"); insn = part[2]
    if (insn ~ /^(v[a-z0-9]+|k(mov|and|or|xor|not|test|ortest|shift|add|unpck)[a-z]*|popcnt|lzcnt|andn|bextr|blsi|blsr|blsmsk|bzhi|pdep|pext|mulx|rorx|sarx|shlx|shrx) / ||
        insn ~ /%[yz]mm/) {
      if (name !~ /lanes_avx/ && name !~ /\[clone \.(avx2|avx512f)(\.[0-9]+)?\]$/ && !(name in seen)) {
        seen[name] = 1; print name
      }
    }
  }' "$work/disassembly.txt" >"$work/leaks.txt"
wide=$(grep -c 'lanes_avx' "$work/disassembly.txt" || true)
if [ -s "$work/leaks.txt" ]; then
  echo "functions outside the lanes_avx builds and the vector clones with instructions beyond baseline x86-64:"
  head -20 "$work/leaks.txt"
  exit 1
fi
[ "$wide" -gt 0 ] || { echo "no AVX2 or AVX-512 build of the query body in the binary"; exit 1; }
echo "portable: no instruction beyond baseline x86-64 outside the AVX2 and AVX-512 query builds and clones"

# 2 and 3 on the default scene, with points on a grid just above the ground and in the air.
"$tool" bake "$src/data/default_scene.glb" -o "$work/native.cbk" -q >/dev/null
awk 'BEGIN { for (i = 0; i < 100; ++i) for (j = 0; j < 100; ++j) {
               printf "%g 0.05 %g\n", -20 + 0.4 * i, -20 + 0.4 * j; printf "%g 1.3 %g\n", -20 + 0.4 * i, -20 + 0.4 * j } }' \
  >"$work/points.txt"
query() {  # LANES_CAP FILE [runner...]: the answers, and the lanes used on stderr
  local cap=$1 out=$2
  shift 2
  CLUSTERBAKE_LANES=$cap "$@" "$tool" query "$work/native.cbk" --light -4,30,2 --points "$work/points.txt" --stats \
    >"$out" 2>"$out.log"
  grep -o 'on [a-z0-9]* lanes' "$out.log" | cut -d' ' -f2
}
native=$(query "" "$work/native.txt")
shadowed=$(grep -c '^1$' "$work/native.txt" || true)
echo "native: $native lanes, $shadowed of $(wc -l <"$work/native.txt") points in shadow"
[ "$shadowed" -gt 0 ]

for cap in sse2 avx2 avx512; do
  picked=$(query "$cap" "$work/$cap.txt")
  cmp -s "$work/native.txt" "$work/$cap.txt" || { echo "CLUSTERBAKE_LANES=$cap ($picked lanes): answers differ"; exit 1; }
  echo "CLUSTERBAKE_LANES=$cap: $picked lanes, the same answers"
done
[ "$(query sse2 "$work/sse2-again.txt")" = sse2 ] || { echo "CLUSTERBAKE_LANES=sse2 did not pick SSE2"; exit 1; }
sun_query() {  # LANES_CAP FILE [runner...]: a sun's answers (its own traversal, float box filters)
  local cap=$1 out=$2
  shift 2
  CLUSTERBAKE_LANES=$cap "$@" "$tool" query "$work/native.cbk" --sun -1,0.4,0.3 --points "$work/points.txt" >"$out"
}
sun_query "" "$work/sun.txt"
[ "$(grep -c '^1$' "$work/sun.txt" || true)" -gt 0 ]
for cap in sse2 avx2 avx512; do
  sun_query "$cap" "$work/sun-$cap.txt"
  cmp -s "$work/sun.txt" "$work/sun-$cap.txt" || { echo "CLUSTERBAKE_LANES=$cap: the sun's answers differ"; exit 1; }
done
echo "a sun: the same answers on every lanes cap"
if CLUSTERBAKE_LANES=avx3 "$tool" query "$work/native.cbk" --light -4,30,2 --points "$work/points.txt" \
  >/dev/null 2>"$work/bad.log"; then
  echo "CLUSTERBAKE_LANES=avx3 was accepted"
  exit 1
fi
grep -q 'CLUSTERBAKE_LANES=avx3: expected sse2, avx2 or avx512' "$work/bad.log"

if ! command -v qemu-x86_64 >/dev/null; then
  echo "SKIPPED: qemu-x86_64 not installed (Debian package qemu-user): the older processors are not emulated"
  exit 0
fi
for cpu in Westmere qemu64; do
  qemu-x86_64 -cpu "$cpu" "$tool" bake "$src/data/default_scene.glb" -o "$work/$cpu.cbk" -q >/dev/null
  cmp "$work/native.cbk" "$work/$cpu.cbk" || { echo "$cpu: the bake differs from the native one"; exit 1; }
  picked=$(query "" "$work/$cpu.txt" qemu-x86_64 -cpu "$cpu")
  [ "$picked" = sse2 ] || { echo "$cpu: picked $picked lanes"; exit 1; }
  cmp -s "$work/native.txt" "$work/$cpu.txt" || { echo "$cpu: answers differ from the native ones"; exit 1; }
  sun_query "" "$work/sun-$cpu.txt" qemu-x86_64 -cpu "$cpu"
  cmp -s "$work/sun.txt" "$work/sun-$cpu.txt" || { echo "$cpu: the sun's answers differ from the native ones"; exit 1; }
  echo "$cpu (emulated): the same asset, and the same answers on sse2 lanes"
done
qemu-x86_64 -cpu Haswell "$tool" bake "$src/data/default_scene.glb" -o "$work/Haswell.cbk" -q >/dev/null
cmp "$work/native.cbk" "$work/Haswell.cbk" || { echo "Haswell: the bake differs from the native one"; exit 1; }
echo "Haswell (emulated, AVX2 clones): the same asset"
