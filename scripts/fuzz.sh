#!/usr/bin/env bash
# Runs the coverage-guided fuzz targets (cargo-fuzz, libFuzzer) for a given time each, keeps what they
# find, and prints the executions run and the crashes found per target. Not part of CI.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]      (default: 600 s; targets decode yaml detect
#                                                          merge pairs grid)
#   scripts/fuzz.sh --runs N [TARGET...]                  (N executions per target instead of a time)
#   FUZZ_RUNS=N scripts/fuzz.sh SECONDS [TARGET...]        (whichever comes first)
#
# With a nightly toolchain the targets run under AddressSanitizer; without one, on stable with
# `--sanitizer none` (coverage guidance works the same). FUZZ_SANITIZER=none forces the latter (about 4x the
# executions a second on the detect target). cargo-fuzz is installed when missing. The targets are built
# with debug assertions (overflow checks included), as tests/house/fuzz_regressions.rs replays the corpus in the
# test profile: an input that only overflows there is a crash here too. FUZZ_DEBUG_ASSERTIONS=0 leaves
# them out (faster).
# Afterwards: the corpus (fuzz/corpus/TARGET) is minimised with `cargo fuzz cmin`, and every crash
# (fuzz/artifacts/TARGET) is copied to fuzz/regressions/TARGET, which tests/house/fuzz_regressions.rs replays
# in the ordinary test suite. Commit both.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"

limit=(-max_total_time="${1:-600}")
label="${1:-600} s"
if [ "${1:-}" = "--runs" ]; then
    limit=(-runs="$2")
    label="a limit of $2 runs"
    shift 2
else
    shift || true
    if [ -n "${FUZZ_RUNS:-}" ]; then
        limit+=(-runs="$FUZZ_RUNS")
        label="$label or $FUZZ_RUNS runs"
    fi
fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(decode yaml detect merge pairs grid)

if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "scripts/fuzz.sh: installing cargo-fuzz" >&2
    cargo install cargo-fuzz --locked
fi
if [ "${FUZZ_SANITIZER:-}" != none ] && rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
    fuzz=(cargo +nightly fuzz)
    sanitizer=(--sanitizer address)
    echo "scripts/fuzz.sh: nightly found: AddressSanitizer on" >&2
else
    fuzz=(cargo fuzz)
    sanitizer=(--sanitizer none)
    echo "scripts/fuzz.sh: running on stable without a sanitizer (FUZZ_SANITIZER=none, or no nightly)" >&2
fi
if [ "${FUZZ_DEBUG_ASSERTIONS:-1}" != 0 ]; then
    sanitizer+=(--debug-assertions)
fi

summary=()
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t" "regressions/$t"
    log="target/fuzz-$t.log"
    mkdir -p target
    before=$(find "artifacts/$t" -type f | wc -l)
    # -rss_limit_mb bounds one input's memory; -max_len lets image seeds grow past the 4 KiB default.
    set +e
    "${fuzz[@]}" run "${sanitizer[@]}" -O "$t" "corpus/$t" -- \
        "${limit[@]}" -rss_limit_mb=2048 -max_len=65536 -timeout=20 \
        -print_final_stats=1 2>&1 | tee "$log" | grep -E '^(#[0-9]+.*(pulse|DONE)|==[0-9]+==|SUMMARY)' || true
    set -e
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
    after=$(find "artifacts/$t" -type f | wc -l)
    crashes=$((after - before))
    find "artifacts/$t" -type f -exec cp {} "regressions/$t/" \;
    "${fuzz[@]}" cmin "${sanitizer[@]}" -O "$t" "corpus/$t" >/dev/null 2>&1 || true
    secs=$(grep -o 'Done [0-9]* runs in [0-9]* second' "$log" | grep -o 'in [0-9]*' | grep -o '[0-9]*' | tail -1 || true)
    summary+=("$t (${sanitizer[*]}): ${execs:-?} executions (${secs:-?} s, $label), $crashes new crashes, $(find "corpus/$t" -type f | wc -l) corpus inputs after cmin")
done
printf '%s\n' "${summary[@]}"
