#!/usr/bin/env bash
# The batch benchmark: `clusterbake batch` on whole libraries, against itself at -j 1 and -j 2 and against
# the sum of single `clusterbake bake` runs. Prints tables of medians and of ratios measured in the same
# round; asserts nothing (it is not a test and is not registered in ctest).
#
#   bench/bench_batch.sh CLUSTERBAKE [DATA] [--runs N] [--copies N] [--small N] [--big-copies K] [--tables LIST]
#
# CLUSTERBAKE  the clusterbake binary (build/cli/clusterbake)
# DATA         the shared scenes, read in place (default: ../shared/data beside the checkout)
# --runs N     rounds measured after one warm-up round (default 5); figures are medians over them
# --copies N   table 2: copies of the small scenes (default 200)
# --small N    table 3: small files beside the large one (default 40)
# --big-copies K  table 3: also a library whose large file is K copies of the ASCII dragon
#              (dragon_vrip_res3.ply, 47,794 triangles) merged into one generated PLY (default 16; 0: none)
# --tables LIST  which tables to run, e.g. 13 (default 123)
#
# 1. Every scene of DATA (a few fail on purpose; they count as files), batch -j 1 and -j 2, --force.
# 2. N copies of six small scenes in their own folders: the sum of single bakes (one process a file, run
#    one after another by a shell loop, the loop timed as a whole), batch -j 1, batch -j 2, and batch on
#    one core (-j 1 --threads 1), the base a -j 2 speedup of 2 would be measured against.
# 3. One large file and many small ones: batch -j 2 (files share the cores), batch -j 2 with every file
#    capped at one thread (a manifest line `FILE --threads 1` each), batch -j 1 (one file at a time).
#
# Each round runs every command of a table once, in an order rotated from round to round; a ratio is taken
# between two commands of the same round, then its median over the rounds. Wall and CPU seconds come from
# bash's `time`. Everything is written in a temporary folder, removed at the end.
set -euo pipefail

prog=bench_batch
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)

die() {  # one line on stderr, exit code 2
    echo "$prog: $*" >&2
    exit 2
}

bin="" data="" runs=5 copies=200 small=40 big_copies=16 tables=123
positional=()
while (($#)); do
    case $1 in
        -h | --help)
            sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//'
            exit 0
            ;;
        --runs | --copies | --small | --big-copies | --tables)
            (($# >= 2)) || die "$1 needs a value"
            [[ $2 =~ ^[0-9]+$ ]] || die "$1 takes a whole number, not '$2'"
            case $1 in
                --runs) runs=$2 ;;
                --copies) copies=$2 ;;
                --small) small=$2 ;;
                --big-copies) big_copies=$2 ;;
                --tables) tables=$2 ;;
            esac
            shift 2
            ;;
        -*) die "unknown option $1 (--help lists them)" ;;
        *)
            positional+=("$1")
            shift
            ;;
    esac
done
((${#positional[@]} >= 1 && ${#positional[@]} <= 2)) ||
    die "usage: bench/bench_batch.sh CLUSTERBAKE [DATA] [--runs N] [--copies N] [--small N] [--big-copies K] [--tables LIST]"
bin=${positional[0]}
data=${positional[1]:-$(dirname "$here")/../shared/data}
((runs >= 1)) || die "--runs must be at least 1"
((copies >= 1 && small >= 1)) || die "--copies and --small must be at least 1"
[[ $tables =~ ^[123]+$ ]] || die "--tables lists table numbers 1, 2 and 3, not '$tables'"
[[ -d $data ]] || die "$data is absent: the benchmarks read their scenes there (or give DATA)"
[[ -x $bin && -f $bin ]] || die "$bin is not an executable file (give the clusterbake binary)"
[[ $bin == */* ]] || bin=./$bin
bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")
data=$(cd "$data" && pwd)

small_scenes=(scanned/kitten.off scanned/bunny_npm.obj scanned/spot_low_resolution.obj scanned/beetle.obj
    gltf/Duck.glb gltf/TestScene/TestScene.gltf)
large_scene=scanned/dragon_vrip_res2_binary.ply
copy_scene=scanned/dragon_vrip_res3.ply  # ASCII: copies are merged with awk
needed=()
[[ $tables == *[23]* ]] && needed+=("${small_scenes[@]}" gltf/TestScene/TestScene.bin)
[[ $tables == *3* ]] && needed+=("$large_scene")
[[ $tables == *3* ]] && ((big_copies > 0)) && needed+=("$copy_scene")
for f in "${needed[@]}"; do
    [[ -f $data/$f ]] || die "$data/$f is absent: tables 2 and 3 are made of it"
done

tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_batch.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
trap 'exit 130' INT TERM

# --- measuring ---------------------------------------------------------------------------------------

status=0  # the exit code of the last timed command

# timed FILE CMD...: runs CMD (output thrown away, stderr kept in $tmp/last.err) and appends
# "wall user sys" seconds to FILE.
timed() {
    local file=$1 TIMEFORMAT='%3R %3U %3S'
    shift
    status=0
    { time "$@" >/dev/null 2>"$tmp/last.err" || status=$?; } 2>>"$file"
}

# rounds CMD...: each CMD (a function taking the file its times go to) once as a warm-up, then $runs
# rounds of every CMD, the order rotated by one each round. Times go to $tmp/CMD.times, a line a round.
rounds() {
    local n=$# r k m
    local cmds=("$@")
    for m in "${cmds[@]}"; do
        rm -f "$tmp/$m.times"
        "$m" /dev/null
    done
    for ((r = 0; r < runs; ++r)); do
        for ((k = 0; k < n; ++k)); do
            m=${cmds[(r + k) % n]}
            "$m" "$tmp/$m.times"
        done
    done
}

rel() {  # a path as the tables print it: TMP/... below the temporary folder
    printf '%s' "${1/#$tmp/TMP}"
}

# The median of the numbers on stdin, one a line.
median() {
    sort -g | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}

wall() { awk '{ print $1 }' "$tmp/$1.times" | median; }
cpu() { awk '{ print $2 + $3 }' "$tmp/$1.times" | median; }
busy() { awk '{ print ($2 + $3) / $1 }' "$tmp/$1.times" | median; }  # cores kept busy: CPU s / wall s

# ratio A B: "median (min-max)" of wall(A)/wall(B) round by round.
ratio() {
    paste -d' ' "$tmp/$1.times" "$tmp/$2.times" | awk '{ print $1 / $4 }' | sort -g >"$tmp/ratios"
    printf '%.2f (%.2f-%.2f)' "$(median <"$tmp/ratios")" "$(head -n1 "$tmp/ratios")" "$(tail -n1 "$tmp/ratios")"
}

# overhead A B: wall(A)/wall(B) - 1 in percent, round by round: "median% (min% to max%)".
overhead() {
    paste -d' ' "$tmp/$1.times" "$tmp/$2.times" | awk '{ print 100 * ($1 / $4 - 1) }' | sort -g >"$tmp/ratios"
    printf '%+.1f%% (%+.1f%% to %+.1f%%)' "$(median <"$tmp/ratios")" "$(head -n1 "$tmp/ratios")" \
        "$(tail -n1 "$tmp/ratios")"
}

# summary OUTDIR: "files baked failed triangles" from OUTDIR/summary.json (triangles: the baked records').
# The dump has one key a line; a record's fields are read up to its closing brace, in whatever order.
summary() {
    awk '
        /"status":/ { st = $2; gsub(/[",]/, "", st) }
        /"triangles":/ { tr = $2; gsub(/,/, "", tr) }
        /^ *},?$/ {
            if (st != "") { files++; if (st == "baked") { baked++; tris += tr } if (st == "failed") failed++ }
            st = ""; tr = 0
        }
        END { printf "%d %d %d %d\n", files, baked, failed, tris }' "$1/summary.json"
}

# batch_ok OUTDIR: the batch just timed finished (exit 0, or 2 when files failed) and baked something.
batch_ok() {
    local s
    if [[ $status != 0 && $status != 2 ]] || [[ ! -f $1/summary.json ]]; then
        die "a batch into $(rel "$1") failed (exit $status): $(head -n1 "$tmp/last.err")"
    fi
    read -r -a s <<<"$(summary "$1")"
    ((s[1] > 0)) || die "a batch into $(rel "$1") baked nothing: $(head -n1 "$tmp/last.err")"
}

thousands() { printf '%s' "$1" | sed ':a; s/\([0-9]\)\([0-9]\{3\}\)\($\|[,.]\)/\1,\2\3/; ta'; }

# row LABEL CMD FILES TRIANGLES [EXTRA]: a table row of CMD's medians.
row() {
    local w c
    w=$(wall "$2")
    c=$(cpu "$2")
    printf '| %s | %.2f | %.1f | %s | %.2f | %.2f |%s\n' "$1" "$w" "$(awk -v n="$3" -v w="$w" 'BEGIN { print n / w }')" \
        "$(thousands "$(awk -v n="$4" -v w="$w" 'BEGIN { printf "%.0f", n / w }')")" "$c" "$(busy "$2")" "${5:+ $5 |}"
}

header() {
    echo "| command | wall s | files/s | triangles/s | CPU s | cores busy |${1:+ $1 |}"
    echo "|---|--:|--:|--:|--:|--:|${1:+--:|}"
}

echo "# clusterbake batch benchmark"
echo
echo "$(date -u +%Y-%m-%d), $(nproc) cores ($(awk -F': ' '/^model name/ { print $2; exit }' /proc/cpuinfo)), $("$bin" --version | head -n1)"
echo "medians of $runs rounds after a warm-up; ratios are taken within a round, then their median (min-max)"
echo "CPU s: user + sys of the whole command; cores busy: CPU s / wall s, run by run (at most the core count)"
echo "TMP: the benchmark's temporary folder; load average (1 min) at the start: $(cut -d' ' -f1 /proc/loadavg)"

# --- 1. every shared scene -----------------------------------------------------------------------------

t1_j1() {
    timed "$1" "$bin" batch "$data" -o "$tmp/t1" --force -q -j 1
    batch_ok "$tmp/t1"
}
t1_j2() {
    timed "$1" "$bin" batch "$data" -o "$tmp/t1" --force -q -j 2
    batch_ok "$tmp/t1"
}

if [[ $tables == *1* ]]; then
    rounds t1_j1 t1_j2
    read -r files baked failed tris <<<"$(summary "$tmp/t1")"
    echo
    echo "## 1. Every scene of DATA: $files files ($baked baked, $failed failed), $(thousands "$tris") triangles baked"
    echo
    echo "reproduce: bench/bench_batch.sh CLUSTERBAKE DATA --runs $runs --tables 1"
    echo "each run:  clusterbake batch DATA -o TMP/t1 --force -q -j 1   (and -j 2)"
    echo
    header
    row "\`batch -j 1\`" t1_j1 "$files" "$tris"
    row "\`batch -j 2\`" t1_j2 "$files" "$tris"
    echo
    echo "speedup, wall -j 1 / -j 2: $(ratio t1_j1 t1_j2)"
fi

# --- 2. many small files -----------------------------------------------------------------------------

# make_copies DIR N: copy i of small scene i mod 6 in its own folder DIR/NNN/ (a glTF with its buffer);
# the copies' paths in `copied`.
copied=()
make_copies() {
    local i scene dir n=${#small_scenes[@]}
    copied=()
    for ((i = 0; i < $2; ++i)); do
        scene=${small_scenes[i % n]}
        dir=$1/$(printf '%03d' "$i")
        mkdir -p "$dir"
        cp "$data/$scene" "$dir/"
        [[ $scene == *.gltf ]] && cp "$data/${scene%.gltf}.bin" "$dir/"
        copied+=("$dir/$(basename "$scene")")
    done
}

# One process a file, one after another, as a plain shell loop would bake a library.
single_bakes() {
    local f i=0
    for f in "${single_files[@]}"; do
        "$bin" bake "$f" -o "$tmp/t2-single/$i.cbk" --force -q || return 1
        i=$((i + 1))
    done
}

t2_single() {
    timed "$1" single_bakes
    ((status == 0)) || die "a single bake failed: $(head -n1 "$tmp/last.err")"
}
t2_j1() {
    timed "$1" "$bin" batch "$tmp/lib2" -o "$tmp/t2" --force -q -j 1
    batch_ok "$tmp/t2"
}
t2_j2() {
    timed "$1" "$bin" batch "$tmp/lib2" -o "$tmp/t2" --force -q -j 2
    batch_ok "$tmp/t2"
}
t2_one_core() {  # the batch on one core: what -j 2 is twice as fast as at best
    timed "$1" "$bin" batch "$tmp/lib2" -o "$tmp/t2" --force -q -j 1 --threads 1
    batch_ok "$tmp/t2"
}

if [[ $tables == *2* ]]; then
    make_copies "$tmp/lib2" "$copies"
    single_files=("${copied[@]}")
    mkdir -p "$tmp/t2-single"
    rounds t2_single t2_j1 t2_j2 t2_one_core
    read -r files baked failed tris <<<"$(summary "$tmp/t2")"
    echo
    echo "## 2. $files copies of ${#small_scenes[@]} small scenes, each in its own folder: $(thousands "$tris") triangles"
    echo
    echo "scenes: ${small_scenes[*]##*/} (TestScene.gltf with its .bin); copy i is of scene i mod ${#small_scenes[@]}"
    echo "reproduce: bench/bench_batch.sh CLUSTERBAKE DATA --runs $runs --copies $copies --tables 2"
    echo "each run:  for f in TMP/lib2/*/*.{off,obj,glb,gltf}; do clusterbake bake \$f -o TMP/t2-single/N.cbk --force -q; done   (the loop timed as a whole)"
    echo "           clusterbake batch TMP/lib2 -o TMP/t2 --force -q -j 1   (and -j 2, and -j 1 --threads 1)"
    echo
    header "against the single bakes"
    row "sum of single bakes" t2_single "$files" "$tris" "-"
    row "\`batch -j 1\`" t2_j1 "$files" "$tris" "$(overhead t2_j1 t2_single)"
    row "\`batch -j 2\`" t2_j2 "$files" "$tris" "$(overhead t2_j2 t2_single)"
    row "\`batch -j 1 --threads 1\` (one core)" t2_one_core "$files" "$tris" "$(overhead t2_one_core t2_single)"
    echo
    echo "speedup, wall -j 1 / -j 2: $(ratio t2_j1 t2_j2); one core / -j 2: $(ratio t2_one_core t2_j2)"
    echo "overhead of batch -j 1 against the sum of single bakes (goal: under 5%; negative: the batch is faster): $(overhead t2_j1 t2_single)"
fi

# --- 3. the split of cores ---------------------------------------------------------------------------

# merge_copies K IN.ply OUT.ply: K copies of an ASCII PLY (x y z first) side by side on a grid, one mesh.
merge_copies() {
    awk -v copies="$1" -v CONVFMT=%.9g '
        BEGIN { part = "header" }
        part == "header" {
            if ($1 == "element" && $2 == "vertex") nv = $3
            else if ($1 == "element" && $2 == "face") nf = $3
            head[++nh] = $0
            if ($1 == "end_header") part = "body"
            next
        }
        { body[++nb] = $0 }
        END {
            side = int(sqrt(copies)); if (side * side < copies) side++
            for (h = 1; h <= nh; h++) {
                line = head[h]
                if (line ~ /^element vertex /) line = "element vertex " nv * copies
                if (line ~ /^element face /) line = "element face " nf * copies
                print line
            }
            for (c = 0; c < copies; c++)
                for (v = 1; v <= nv; v++) {
                    n = split(body[v], f, " ")
                    f[1] += 0.25 * (c % side); f[3] += 0.25 * int(c / side)
                    line = f[1]; for (k = 2; k <= n; k++) line = line " " f[k]
                    print line
                }
            for (c = 0; c < copies; c++)
                for (t = nv + 1; t <= nv + nf; t++) {
                    n = split(body[t], f, " ")
                    line = f[1]; for (k = 2; k <= n; k++) line = line " " (f[k] + c * nv)
                    print line
                }
        }' "$2" >"$3"
}

# make_library LIB LARGE: the large file (linked, so read in place) and $small copies of the small scenes;
# LIB/capped.txt is the manifest that lists every file with --threads 1.
make_library() {
    local f
    mkdir -p "$1"
    ln -s "$2" "$1/$(basename "$2")"
    make_copies "$1" "$small"
    {
        echo "# every file capped at one thread"
        echo "$(basename "$2") --threads 1"
        for f in "${copied[@]}"; do echo "${f#"$1/"} --threads 1"; done
    } >"$1/capped.txt"
}

# The library table 3 measures, and its three commands.
lib3=""
t3_shared() {
    timed "$1" "$bin" batch "$lib3" -o "$lib3.out" --force -q -j 2
    batch_ok "$lib3.out"
}
t3_capped() {
    timed "$1" "$bin" batch "$lib3/capped.txt" -o "$lib3.out" --force -q -j 2
    batch_ok "$lib3.out"
}
t3_one() {
    timed "$1" "$bin" batch "$lib3" -o "$lib3.out" --force -q -j 1
    batch_ok "$lib3.out"
}

split_table() {  # split_table LIB TITLE
    local files baked failed tris
    lib3=$1
    rounds t3_shared t3_capped t3_one
    read -r files baked failed tris <<<"$(summary "$lib3.out")"
    echo
    echo "## 3. $2 and $((files - 1)) small files: $(thousands "$tris") triangles"
    echo
    echo "reproduce: bench/bench_batch.sh CLUSTERBAKE DATA --runs $runs --small $small --big-copies $big_copies --tables 3"
    echo "each run:  (a) clusterbake batch $(rel "$lib3") -o OUT --force -q -j 2"
    echo "           (b) clusterbake batch $(rel "$lib3")/capped.txt -o OUT --force -q -j 2   (each line: FILE --threads 1)"
    echo "           (c) clusterbake batch $(rel "$lib3") -o OUT --force -q -j 1"
    echo
    header "wall against (c)"
    row "(a) \`batch -j 2\`, cores shared" t3_shared "$files" "$tris" "$(ratio t3_shared t3_one)"
    row "(b) \`batch -j 2\`, 1 thread a file" t3_capped "$files" "$tris" "$(ratio t3_capped t3_one)"
    row "(c) \`batch -j 1\`" t3_one "$files" "$tris" "1"
    echo
    echo "wall (a) / (b): $(ratio t3_shared t3_capped)"
}

if [[ $tables == *3* ]]; then
    make_library "$tmp/lib3" "$data/$large_scene"
    split_table "$tmp/lib3" "the dragon ($large_scene, linked in place)"
    if ((big_copies > 0)); then
        merge_copies "$big_copies" "$data/$copy_scene" "$tmp/dragons.ply"
        make_library "$tmp/lib3big" "$tmp/dragons.ply"
        split_table "$tmp/lib3big" "$big_copies copies of $copy_scene merged into one PLY (generated)"
    fi
fi

echo
echo "load average (1 min) at the end: $(cut -d' ' -f1 /proc/loadavg)"
