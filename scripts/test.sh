#!/usr/bin/env bash
# The project's test command (the README's "run the tests"); .ci/run calls it. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v cargo >/dev/null 2>&1; then
    echo "scripts/test.sh: cargo not found; install the Rust toolchain with rustup first (see README)" >&2
    exit 1
fi

if [ -z "${OGM_MAPS_DIR:-}" ] && [ ! -d ../shared/maps ]; then
    echo "scripts/test.sh: NOTE: ../shared/maps not found; the real-map tests will say SKIPPED (and fail under CI=true)" >&2
fi

# Unit, integration and doc tests. The dev profile is optimised (Cargo.toml), so real maps stay quick.
cargo test --locked
