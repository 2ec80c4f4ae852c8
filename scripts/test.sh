#!/usr/bin/env bash
# The project's test command (the README's "run the tests"); .ci/run calls it. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v cargo >/dev/null 2>&1; then
    echo "scripts/test.sh: cargo not found; install the Rust toolchain with rustup first (see README)" >&2
    exit 1
fi

# GPU tests run on a Vulkan adapter; with none present, install Mesa's lavapipe (a software Vulkan driver).
have_vulkan() {
    # No `grep -q`: it would close the pipe early and pipefail would report ldconfig's SIGPIPE.
    ldconfig -p 2>/dev/null | grep 'libvulkan\.so\.1' >/dev/null || return 1
    for f in /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json; do
        [ -e "$f" ] && return 0
    done
    return 1
}
if ! have_vulkan; then
    echo "scripts/test.sh: no Vulkan driver found; installing mesa-vulkan-drivers (lavapipe)" >&2
    sudo=""
    if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -qq
    $sudo apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers libvulkan1 >/dev/null
    have_vulkan || { echo "scripts/test.sh: installing lavapipe did not give a Vulkan driver" >&2; exit 1; }
fi

if [ -z "${OGM_MAPS_DIR:-}" ] && [ ! -d ../shared/maps ]; then
    echo "scripts/test.sh: NOTE: ../shared/maps not found; the real-map tests will say SKIPPED (and fail under CI=true)" >&2
fi

# OpenCV (for the Harris / Shi-Tomasi agreement test) in a virtual environment under target/.
venv=target/opencv-venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import cv2, numpy" 2>/dev/null; then
    echo "scripts/test.sh: setting up $venv with opencv-python-headless" >&2
    if ! python3 -m venv --help >/dev/null 2>&1 || ! python3 -c "import ensurepip" 2>/dev/null; then
        sudo=""
        if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
        export DEBIAN_FRONTEND=noninteractive
        $sudo apt-get update -qq
        $sudo apt-get install -y -qq python3-venv >/dev/null
    fi
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check opencv-python-headless numpy
fi

# Unit, integration and doc tests. The dev profile is optimised (Cargo.toml), so real maps stay quick.
cargo test --locked
