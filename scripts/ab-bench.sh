#!/usr/bin/env bash
# Before/after: two builds of the tool timed in turn (A B A B ...) with the same `bench` arguments, each
# detector's median per run paired A with B, so that a drift in the machine's speed moves both. Prints, per
# map size and detector, the median over the rounds of each build's median and of the ratio A/B.
#
#   scripts/ab-bench.sh OLD_BINARY NEW_BINARY [ROUNDS] -- BENCH_ARGS...
#   e.g. scripts/ab-bench.sh /tmp/ogm-old target/release/ogm-corners 5 -- --size 4096x4096 --detector all --backend cpu
set -euo pipefail
a=$1 b=$2
rounds=5
shift 2
if [ "${1:-}" != "--" ]; then rounds=$1; shift; fi
[ "${1:-}" = "--" ] && shift
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
for i in $(seq "$rounds"); do
    "$a" bench "$@" --format json >"$dir/a$i.json"
    "$b" bench "$@" --format json >"$dir/b$i.json"
done
python3 - "$dir" "$rounds" "$a" "$b" <<'PY'
import json, statistics, sys
d, n, a, b = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
def ms(path):
    return {(r["width"], r["height"], r["detector"], r["backend"]): r["median_ms"]
            for r in json.load(open(path))["records"] if r["stage"] == "end_to_end"}
runs = [(ms(f"{d}/a{i}.json"), ms(f"{d}/b{i}.json")) for i in range(1, n + 1)]
info = json.load(open(f"{d}/b1.json"))
print(f"# A = {a}, B = {b}; {n} rounds A B A B; {info['cpu']}, {info['threads']} threads")
print("| size | detector | backend | A median ms | B median ms | A / B (paired, median) |")
print("|---|---|---|---|---|---|")
for k in runs[0][0]:
    if not all(k in x and k in y for x, y in runs):
        continue
    am = statistics.median(x[k] for x, _ in runs)
    bm = statistics.median(y[k] for _, y in runs)
    ratio = statistics.median(x[k] / y[k] for x, y in runs)
    print(f"| {k[0]}x{k[1]} | {k[2]} | {k[3]} | {am:.2f} | {bm:.2f} | {ratio:.2f} |")
PY
