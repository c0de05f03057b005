#!/usr/bin/env bash
# scripts/clusterbake-dask on a real Dask cluster: a scheduler and two one-thread workers on 127.0.0.1 bake a
# folder of real scenes plus one broken file; one worker is killed (SIGKILL) while it bakes. Checks: exit
# code 2, the broken file failed with its error line in summary.json, every other file baked by the Dask run
# is byte-identical to a local `clusterbake batch` of the same folder (the killed worker's file included),
# and a second run finds every good file up to date.
# Usage: check_dask.sh CLUSTERBAKE WORKDIR SHARED_DATA_DIR (CB_SHARED_DATA_DIR, when set, names another)
set -euo pipefail
export LC_ALL=C  # a decimal point in $EPOCHREALTIME, byte order in sort
src=$(cd "$(dirname "$0")/.." && pwd)
tool=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
work=$2
shared=${CB_SHARED_DATA_DIR:-$3}
python=${CB_PYTHON:-/usr/bin/python3}  # Debian's, with python3-distributed
driver=$src/scripts/clusterbake-dask

pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -KILL -- "-$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT
trap 'echo "check_dask: FAIL: line $LINENO: $BASH_COMMAND" >&2' ERR
die() {
  echo "check_dask: FAIL: $*" >&2
  exit 1
}
# The pid of a `clusterbake bake` that process $1 runs, if any (from /proc: no procps needed).
bake_child() {
  local stat pid ppid
  for stat in /proc/[0-9]*/stat; do
    read -r pid _ _ ppid _ <"$stat" 2>/dev/null || continue
    [ "$ppid" = "$1" ] || continue
    if tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null | grep -q ' bake '; then
      echo "$pid"
      return
    fi
  done
}

rm -rf "$work"
mkdir -p "$work/scenes" "$work/logs"
cd "$work"

# The scenes: several formats (a .gltf with external .bin buffers, Draco .glb and .gltf), in copies under
# several folders so that the run lasts a few seconds, and a text file named .glb that must fail.
if [ -d "$shared/scanned" ] && [ -d "$shared/gltf" ]; then
  echo "check_dask: scenes from $shared"
  for copy in a b/nested; do
    mkdir -p "scenes/$copy/scanned"
    cp -r "$shared/gltf/CesiumMilkTruck" "$shared/gltf/BoxDraco" "$shared/gltf/Box_Draco.glb" \
      "$shared/gltf/CesiumMilkTruck_draco.glb" "$shared/gltf/Duck.glb" "$shared/hard/featuretype.STL" \
      "$shared/hard/3dfier_testarea" "scenes/$copy/"
  done
  cp "$shared"/scanned/* scenes/a/scanned/
  find "$shared/scanned" -type f -size -1000k -exec cp {} scenes/b/nested/scanned/ \;  # the five largest once
else
  echo "check_dask: no shared scenes at $shared: copies of the project's data/ instead"
  for copy in a b/nested c d/deeper e f g/h/i j; do
    mkdir -p "scenes/$copy"
    cp "$src/data/default_scene.glb" "$src"/data/small/{cube.obj,cube_ascii.ply,cube_binary.stl,primitive_modes.gltf} \
      "scenes/$copy/"
  done
fi
mkdir -p scenes/broken
echo "this is a text file, not a glTF binary" >scenes/broken/notes.glb
scenes=$(find scenes -type f | grep -ciE '\.(gltf|glb|obj|ply|off|stl)$')

# The reference: a local batch of the same folder.
status=0
"$tool" batch "$work/scenes" -o "$work/local" -j 2 -q >logs/local.txt 2>&1 || status=$?
[ "$status" -eq 2 ] || die "clusterbake batch exited with $status, not 2 (logs/local.txt)"

# The cluster: a scheduler on a free port (its address in a file) and two workers, each in its own process
# group so that killing one kills its running bake as losing its machine would.
setsid "$python" -m distributed.cli.dask_scheduler --host 127.0.0.1 --port 0 --no-dashboard \
  --scheduler-file "$work/scheduler.json" >logs/scheduler.txt 2>&1 &
pids+=($!)
for i in 1 2; do
  for _ in $(seq 100); do [ -s scheduler.json ] && break; sleep 0.1; done
  setsid "$python" -m distributed.cli.dask_worker --scheduler-file "$work/scheduler.json" --nthreads 1 \
    --no-nanny --no-dashboard --host 127.0.0.1 --name "worker$i" --local-directory "$work/worker$i" \
    >"logs/worker$i.txt" 2>&1 &
  pids+=($!)
  workers[i]=$!
done
for _ in $(seq 300); do
  [ "$(cat logs/worker?.txt | grep -c 'Registered to')" -eq 2 ] && break
  sleep 0.1
done
[ "$(cat logs/worker?.txt | grep -c 'Registered to')" -eq 2 ] || die "the workers did not start (logs/)"
address=$("$python" -c 'import json, sys; print(json.load(open(sys.argv[1]))["address"])' scheduler.json)

# The run, and a worker killed while it bakes, once some files are done.
start=$EPOCHREALTIME
timeout 120 "$driver" --scheduler "$address" --clusterbake "$tool" "$work/scenes" -o "$work/dask" \
  >logs/dask1.txt 2>logs/dask1.err &
driver_pid=$!
killed=""
for _ in $(seq 600); do
  done_files=$(find dask -name '*.cbk' 2>/dev/null | wc -l || true)
  if [ "$done_files" -ge 3 ]; then
    for i in 1 2; do  # stopped first, so that the bake seen running is the one killed
      kill -STOP -- "-${workers[i]}"
      bake=$(bake_child "${workers[i]}")
      if [ -z "$bake" ]; then
        kill -CONT -- "-${workers[i]}"
        continue
      fi
      killed=$(tr '\0' ' ' <"/proc/$bake/cmdline" | sed 's/.* -o \([^ ]*\) .*/\1/')
      { kill -KILL -- "-${workers[i]}" && wait "${workers[i]}"; } 2>/dev/null || true
      echo "check_dask: killed worker$i after $done_files files, while it baked ${killed#"$work"/}"
      break 2
    done
  fi
  kill -0 "$driver_pid" 2>/dev/null || break
  sleep 0.05
done
status=0
wait "$driver_pid" || status=$?
seconds=$(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN { print b - a }')
[ -n "$killed" ] || die "the run ended before a worker could be killed mid-bake (logs/dask1.*)"
[ "$status" -eq 2 ] || die "clusterbake-dask exited with $status, not 2 (logs/dask1.*)"
if [ "$(tail -n 2 logs/dask1.txt | head -n 1)" != "failed:" ] ||
  ! tail -n 1 logs/dask1.txt | grep -q '^  .*/notes\.glb: '; then
  die "the broken file is not listed last as failed (logs/dask1.txt)"
fi
[ -f "$killed" ] || die "the file whose worker was killed was not baked again: $killed"

# summary.json: every file once, sorted; the broken one failed with its error line, every other made by
# this run (dask/ was empty). A file may show as up to date: the killed worker baked it, but its result was
# lost with the worker and the rerun found the asset written.
"$python" - dask/summary.json local/summary.json "$scenes" <<'EOF' || die "summary.json"
import json, sys
dask, local, scenes = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), int(sys.argv[3])
files = dask["files"]
names = [f["name"] for f in files]
assert dask["engine"] == "dask" and dask["tool"] == local["tool"] and dask["format"] == local["format"], dask
assert dask["jobs"] >= 1, dask["jobs"]
assert names == sorted(names) and len(names) == scenes, (len(names), scenes)
assert names == [f["name"] for f in local["files"]], "not the files of the local batch"
counts = dask["counts"]
assert counts["failed"] == 1 and counts["baked"] + counts["up_to_date"] == scenes - 1, counts
assert counts["up_to_date"] <= 2, counts
broken = next(f for f in files if f["name"] == "broken/notes.glb")
assert broken["status"] == "failed" and "notes.glb" in broken["error"] and "\n" not in broken["error"], broken
assert broken["error"] == next(f for f in local["files"] if f["name"] == "broken/notes.glb")["error"], broken
for d, l in zip(files, local["files"]):
    keys = ("input_bytes", "triangles", "clusters", "coarse_clusters", "output_bytes")
    assert all(d[k] == l[k] for k in keys), (d, l)
    assert (d["status"] == "failed") == (l["status"] == "failed"), (d, l)
    assert d["status"] == "failed" or (d["error"] == "" and d["triangles"] > 0 and d["output_bytes"] > 0), d
EOF

# Every asset byte for byte as the local batch wrote it, and no other file.
compare_outputs() {
  local n=0
  while read -r asset; do
    cmp "local/$asset" "dask/$asset" || die "dask/$asset differs from the local batch's"
    n=$((n + 1))
  done < <(cd local && find . -name '*.cbk' | sort)
  [ "$n" -eq $((scenes - 1)) ] || die "the local batch wrote $n assets, not $((scenes - 1))"
  [ "$(cd dask && find . -type f ! -name summary.json | wc -l)" -eq "$n" ] ||
    die "dask/ holds other files: $(cd dask && find . -type f ! -name summary.json ! -name '*.cbk' | tr '\n' ' ')"
  echo "$n"
}
assets=$(compare_outputs)

# A second run: every good file up to date, the broken one failed again.
status=0
timeout 120 "$driver" --scheduler "$address" --clusterbake "$tool" "$work/scenes" -o "$work/dask" -q \
  >logs/dask2.txt 2>&1 || status=$?
[ "$status" -eq 2 ] || die "the second run exited with $status, not 2 (logs/dask2.txt)"
"$python" -c '
import json, sys
s = json.load(open(sys.argv[1]))
n = int(sys.argv[2])
assert s["counts"] == {"baked": 0, "up_to_date": n - 1, "failed": 1}, s["counts"]
' dask/summary.json "$scenes" || die "the second run did not find every good file up to date"
compare_outputs >/dev/null

printf 'check_dask: %d scenes, %d assets identical to the local batch, broken file failed, ' "$scenes" "$assets"
printf 'a worker killed mid-run, second run all up to date; first run %.1f s\n' "$seconds"
