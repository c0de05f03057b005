#!/usr/bin/env bash
# clusterbake batch as an asset build runs it: a library of real scenes with broken files among them, baked
# with one and two files at once, incrementally, killed with SIGKILL and resumed, and from a manifest.
# Every output must equal a single `clusterbake bake` of its file.
# Usage: check_batch.sh CLUSTERBAKE SOURCE_DIR WORK_DIR [SHARED_DATA_DIR]
set -euo pipefail
tool=$1
src=$2
work=$3
shared=${4:-}
rm -rf "$work"
mkdir -p "$work/lib/broken"
cd "$work"
fail() {
  echo "check_batch: FAILED: $*" >&2
  exit 1
}

# The library: the shared scenes when present (the largest left out to keep the test short), else the
# project's own data. Copied, since the test edits one file.
if [ -n "$shared" ] && [ -d "$shared/scanned" ]; then
  cp -r "$shared/gltf" "$shared/hard" lib/
  mkdir -p lib/scanned
  for f in bunny_npm.obj dragon_vrip_res4.ply horse.ply kitten.off fandisk.obj teapot.obj beetle.obj; do
    cp "$shared/scanned/$f" lib/scanned/
  done
  edited=lib/scanned/teapot.obj
else
  echo "check_batch: no shared data at '${shared}': the project's own data/ only"
  cp "$src/data/default_scene.glb" lib/
  mkdir -p lib/small
  # One file per name: cube.obj and cube.off would both write small/cube.cbk, which batch refuses.
  cp "$src"/data/small/{cube.obj,cube_binary.ply,cube_ascii.stl,primitive_modes.gltf} lib/small/
  edited=lib/small/cube.obj
fi
printf 'this is a text file, not a glTF\n' >lib/broken/not_a_scene.glb
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n' >lib/broken/bad_index.obj
assimp=/usr/share/assimp/models/glTF2  # Debian's assimp-testmodels: indices out of range, infinities, no .bin
if [ -d "$assimp/IndexOutOfRange" ]; then
  mkdir -p lib/broken/assimp
  cp -r "$assimp/IndexOutOfRange" "$assimp/BoxWithInfinites-glTF-Binary" "$assimp/MissingBin" lib/broken/assimp/
fi
scenes() { grep -iE '\.(gltf|glb|obj|ply|off|stl)$' || true; }
total=$(find lib -type f | scenes | wc -l)
broken=$(find lib/broken -type f | scenes | wc -l)
[ -f lib/hard/inf_nan.obj ] && broken=$((broken + 1))  # non-finite coordinates
good=$((total - broken))
echo "check_batch: $total scene files, $good of them good"

count() { # count STATUS SUMMARY
  python3 -c "import json,sys; print(sum(f['status'] == sys.argv[1] for f in json.load(open(sys.argv[2]))['files']))" "$1" "$2"
}
same_tree() { # every .cbk of $1 and $2 identical, and the same set of them
  diff <(cd "$1" && find . -name '*.cbk' | sort) <(cd "$2" && find . -name '*.cbk' | sort) >/dev/null ||
    fail "$1 and $2 hold different files"
  (cd "$1" && find . -name '*.cbk' -print0) | while IFS= read -r -d '' f; do
    cmp -s "$1/$f" "$2/$f" || fail "$1/$f differs from $2/$f"
  done
}

# One file at a time, then two: exit 2 (some failed), the same bytes.
set +e
"$tool" batch lib -o out1 -j 1 -q >/dev/null 2>&1
rc1=$?
"$tool" batch lib -o out2 -j 2 >printed.txt 2>lines.txt
rc2=$?
set -e
[ "$rc1" = 2 ] && [ "$rc2" = 2 ] || fail "exit codes $rc1 and $rc2, expected 2 (some files failed)"
[ "$(count baked out1/summary.json)" = "$good" ] || fail "out1: $(count baked out1/summary.json) baked, expected $good"
[ "$(count failed out2/summary.json)" = "$broken" ] || fail "out2: wrong failure count"
same_tree out1 out2
grep -q "^failed      lib/broken/not_a_scene.glb: " lines.txt || fail "no failure line for the text file"
failures=$broken
tail -n $((failures + 1)) printed.txt | head -n 1 | grep -qx "failed:" || fail "the failures are not listed last"
tail -n "$failures" printed.txt | grep -q "^  lib/broken/not_a_scene.glb: " || fail "the text file is not among the failures"
python3 - out2/summary.json <<'PY' || fail "summary.json records"
import json, sys
s = json.load(open(sys.argv[1]))
by_name = {f["name"]: f for f in s["files"]}
assert [f["name"] for f in s["files"]] == sorted(by_name), "records not sorted by name"
bad = by_name["broken/not_a_scene.glb"]
assert bad["status"] == "failed" and bad["error"].startswith("lib/broken/not_a_scene.glb: "), bad
for f in s["files"]:
    if f["status"] == "baked":
        assert f["triangles"] > 0 and f["clusters"] > 0 and f["output_bytes"] > 0 and f["input_bytes"] > 0, f
        assert f["error"] == "", f
assert s["counts"]["failed"] == sum(f["status"] == "failed" for f in s["files"])
PY

# Each output equals a single bake of its file.
for f in $(cd lib && find . -type f | grep -iE '\.(gltf|glb|obj|ply|off|stl)$' | grep -v broken | grep -v inf_nan | head -n 12); do
  out=out1/${f%.*}.cbk
  "$tool" bake "lib/$f" -o single.cbk >/dev/null
  cmp -s single.cbk "$out" || fail "batch output $out differs from a single bake of lib/$f"
done

# Incremental: nothing to do, then only the edited file, then everything with --force.
set +e
"$tool" batch lib -o out2 -q >/dev/null 2>&1
[ "$(count up-to-date out2/summary.json)" = "$good" ] || fail "second run: not every good file up to date"
[ "$(count baked out2/summary.json)" = 0 ] || fail "second run baked something"
echo "# edited" >>"$edited"
"$tool" batch lib -o out2 -q >/dev/null 2>&1
python3 -c "import json,sys; f=[r['name'] for r in json.load(open('out2/summary.json'))['files'] if r['status']=='baked']; assert f == [sys.argv[1]], f" \
  "${edited#lib/}" || fail "after editing $edited, not only it was baked"
"$tool" batch lib -o out2 -q --force >/dev/null 2>&1
[ "$(count baked out2/summary.json)" = "$good" ] || fail "--force did not bake every good file"
set -e
rm -rf out1  # the reference again, with the edited file
"$tool" batch lib -o out1 -q >/dev/null 2>&1 || true

# SIGKILL at any moment: every output present is whole, and the same command finishes the rest. The last
# kill waits for the first output, wherever it lands in time on a loaded machine.
resumed_some=0
for delay in 0.05 0.2 0.4 0.7 1.0 1.5 first-output; do
  rm -rf out3
  "$tool" batch lib -o out3 -j 2 -q >/dev/null 2>&1 &
  pid=$!
  if [ "$delay" = first-output ]; then
    for _ in $(seq 6000); do
      [ -n "$(find out3 -name '*.cbk' 2>/dev/null | head -1)" ] && break
      sleep 0.01
    done
  else
    sleep "$delay"
  fi
  kill -9 "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true
  if [ -d out3 ]; then
    find out3 -name '*.cbk' -print0 | while IFS= read -r -d '' f; do
      cmp -s "$f" "out1/${f#out3/}" || fail "killed after ${delay} s: $f is not a whole output"
    done
  fi
  set +e
  "$tool" batch lib -o out3 -j 2 -q >/dev/null 2>&1
  rc=$?
  set -e
  [ "$rc" = 2 ] || fail "resumed batch exit code $rc"
  same_tree out1 out3
  [ -z "$(find out3 -name '*.tmp*')" ] || fail "temporaries left after the resumed batch"
  [ "$(count up-to-date out3/summary.json)" -gt 0 ] && resumed_some=1
done
[ "$resumed_some" = 1 ] || fail "no kill landed mid-batch (every resume started from nothing)"

# A manifest with per-file options, and what --plan prints.
first=$(cd lib && find . -type f -iname '*.obj' | grep -v broken | grep -v inf_nan | sort | head -n 1)
second=$(cd lib && find . -type f -iname '*.ply' | sort | head -n 1)
printf '# two scenes\n%s --fine 8 --bounds all\n\n"%s"\n' "$first" "$second" >lib/list.txt
"$tool" batch lib/list.txt -o out4 -q >/dev/null
"$tool" bake "lib/$first" -o single.cbk --fine 8 --bounds all >/dev/null
cmp -s single.cbk "out4/${first%.*}.cbk" || fail "manifest options were not applied to $first"
cmp -s "out1/${second%.*}.cbk" "out4/${second%.*}.cbk" || fail "manifest output of $second differs"
"$tool" batch lib/list.txt -o out5 --plan >plan.txt
[ "$(wc -l <plan.txt)" = 2 ] || fail "--plan printed $(wc -l <plan.txt) lines for 2 files"
mkdir -p out5
python3 - "$tool" plan.txt <<'PY' || fail "a --plan job did not make the batch's output"
import json, subprocess, sys
for line in open(sys.argv[2]):
    job = json.loads(line)
    import os; os.makedirs(os.path.dirname(job["output"]), exist_ok=True)
    out = json.loads(subprocess.run([sys.argv[1]] + job["argv"], check=True, capture_output=True).stdout)
    assert out["status"] == "baked", out
    ref = "out4/" + job["name"].rsplit(".", 1)[0] + ".cbk"
    assert open(job["output"], "rb").read() == open(ref, "rb").read(), job["name"]
PY

# Usage errors: one line, exit code 2, nothing made.
expect_usage() { # expect_usage TEXT ARGS...
  local text=$1
  shift
  set +e
  "$tool" "$@" >usage.out 2>usage.err
  local rc=$?
  set -e
  [ "$rc" = 2 ] || fail "'$*' exited $rc, expected 2"
  [ "$(wc -l <usage.err)" = 1 ] && grep -qF "$text" usage.err || fail "'$*' said: $(cat usage.err)"
}
touch afile
expect_usage "afile: exists and is not a folder" batch lib -o afile
printf 'readme.md\n' >lib/bad_list.txt
expect_usage "bad_list.txt: line 1: " batch lib/bad_list.txt -o out6
printf '%s --fine 0\n' "$first" >lib/bad_options.txt
expect_usage "bad_options.txt: line 1: --fine" batch lib/bad_options.txt -o out6
[ ! -e out6 ] || fail "a refused batch made its output folder"
echo "check_batch: $good good files: -j 1 and -j 2 identical and equal to single bakes; incremental, SIGKILL-safe, manifest and --plan checked"
