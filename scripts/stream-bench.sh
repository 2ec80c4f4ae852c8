#!/usr/bin/env bash
# Streamed detection of a map larger than the machine's taste for it (docs/guide.md and docs/performance.md, "Maps of any size"):
# the tool writes a SIDE x SIDE synthetic office PGM row by row, then `ogm-corners detect` reads it back,
# timed end to end with its peak resident memory, beside the disk's own sequential read (dd) in the same
# cache state. Cold runs drop the page cache first (root only); warm runs read the file once before.
#
#   scripts/stream-bench.sh [SIDE] [DIR]     (defaults: 100000, target/stream-bench)
#   RUNS=3 (OGM runs per cache state)  BASELINE_RUNS=1  DETECTORS="ogm harris shi-tomasi trajkovic"
#
# The 100000^2 map is a 10 GB file: it needs 10 GB of disk, about a minute to write, and (cold) root.
set -euo pipefail
cd "$(dirname "$0")/.."
side=${1:-100000}
dir=${2:-target/stream-bench}
runs=${RUNS:-3}
baseline_runs=${BASELINE_RUNS:-1}
detectors=${DETECTORS:-ogm harris shi-tomasi trajkovic}
bin=target/release/ogm-corners

cargo build --release --locked --bin ogm-corners >&2
mkdir -p "$dir"
map=$dir/synthetic-${side}x${side}.pgm
if [ ! -f "$map" ]; then
    /usr/bin/time -f "wrote $map in %e s, peak %M KB" \
        "$bin" bench --size "${side}x${side}" --write-map "$map" >&2
fi
bytes=$(stat -c %s "$map")
px=$((side * side))

can_drop=0
if [ -w /proc/sys/vm/drop_caches ]; then can_drop=1; fi
drop() { sync; echo 3 >/proc/sys/vm/drop_caches; }

# Seconds dd takes to read the file sequentially.
dd_secs() {
    local t0 t1
    t0=$(date +%s.%N)
    dd if="$map" of=/dev/null bs=16M status=none
    t1=$(date +%s.%N)
    awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }'
}

median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }

printf '# %s: %d bytes, %d x %d, %s, %s\n' "$map" "$bytes" "$side" "$side" \
    "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')" "$(nproc) threads"
printf '| cache | detector | runs | disk (dd) MB/s | detect s | detect MB/s | detect Mpx/s | detect / disk | peak RSS MB | keypoints |\n'
printf '|---|---|---|---|---|---|---|---|---|---|\n'
for cache in cold warm; do
    if [ "$cache" = cold ] && [ "$can_drop" = 0 ]; then
        echo "# cold runs skipped: dropping the page cache needs root" >&2
        continue
    fi
    if [ "$cache" = warm ]; then cat "$map" >/dev/null; fi
    for det in $detectors; do
        n=$runs
        if [ "$det" != ogm ]; then n=$baseline_runs; fi
        : >"$dir/dd.txt"
        : >"$dir/detect.txt"
        : >"$dir/rss.txt"
        for _ in $(seq "$n"); do
            if [ "$cache" = cold ]; then drop; fi
            dd_secs >>"$dir/dd.txt"
            if [ "$cache" = cold ]; then drop; fi
            /usr/bin/time -f '%e %M' -o "$dir/time.txt" \
                "$bin" detect "$map" --backend cpu --detector "$det" -o "$dir/keypoints.csv" 2>/dev/null
            cut -d' ' -f1 "$dir/time.txt" >>"$dir/detect.txt"
            cut -d' ' -f2 "$dir/time.txt" >>"$dir/rss.txt"
        done
        d=$(median <"$dir/dd.txt")
        t=$(median <"$dir/detect.txt")
        rss=$(sort -g "$dir/rss.txt" | tail -1)
        k=$(($(wc -l <"$dir/keypoints.csv") - 1))
        awk -v c="$cache" -v det="$det" -v n="$n" -v b="$bytes" -v px="$px" -v d="$d" -v t="$t" \
            -v rss="$rss" -v k="$k" 'BEGIN {
                printf "| %s | %s | %d | %.0f | %.2f | %.0f | %.0f | %.2f | %.0f | %d |\n",
                    c, det, n, b / d / 1e6, t, b / t / 1e6, px / t / 1e6, d / t, rss / 1024, k }'
    done
done
