#!/usr/bin/env bash
# The project's test command (the README's "run the tests"); .ci/run calls it. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each phase's end, with the seconds since the start: CI's log says where its time goes.
phase() { echo "scripts/test.sh: [${SECONDS} s] $*" >&2; }

if ! command -v cargo >/dev/null 2>&1; then
    echo "scripts/test.sh: cargo not found; install the Rust toolchain with rustup first (see README)" >&2
    exit 1
fi

# Debian packages, installed with sudo when not root; fails when apt-get does.
apt_install() {
    local sudo=""
    if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -qq && $sudo apt-get install -y -qq "$@" >/dev/null
}

# GPU tests run on a Vulkan adapter; with none present, install Mesa's lavapipe (a software Vulkan driver).
have_vulkan() {
    # No `grep -q`: it would close the pipe early and pipefail would report ldconfig's SIGPIPE.
    ldconfig -p 2>/dev/null | grep 'libvulkan\.so\.1' >/dev/null || return 1
    for f in /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json; do
        [ -e "$f" ] && return 0
    done
    return 1
}
install_vulkan() {
    have_vulkan && return 0
    echo "scripts/test.sh: no Vulkan driver found; installing mesa-vulkan-drivers (lavapipe)" >&2
    apt_install --no-install-recommends mesa-vulkan-drivers libvulkan1
    have_vulkan || { echo "scripts/test.sh: installing lavapipe did not give a Vulkan driver" >&2; exit 1; }
}

if [ -z "${OGM_MAPS_DIR:-}" ] && [ ! -d ../shared/maps ]; then
    echo "scripts/test.sh: NOTE: ../shared/maps not found; the real-map tests will say SKIPPED (and fail under CI=true)" >&2
fi

# A virtual environment under target/ with the given PyPI packages (made once, remade when one is missing).
python_env() {
    local venv=$1 check=$2
    shift 2
    if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c "$check" 2>/dev/null; then
        return 0
    fi
    echo "scripts/test.sh: setting up $venv with $*" >&2
    if ! python3 -m venv --help >/dev/null 2>&1 || ! python3 -c "import ensurepip" 2>/dev/null; then
        apt_install python3-venv
    fi
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check "$@"
}

# Headless Chromium and its WebDriver, for the HTML report tests (tests/browser): installed when missing. A
# machine where they cannot be installed skips those tests loudly (and fails under CI=true).
have_browser() {
    command -v chromedriver >/dev/null 2>&1 || [ -n "${CHROMEDRIVER_BIN:-}" ] || return 1
    [ -n "${CHROMIUM_BIN:-}" ] && return 0
    for b in chromium chromium-browser google-chrome google-chrome-stable; do
        command -v "$b" >/dev/null 2>&1 && return 0
    done
    return 1
}
install_browser() {
    have_browser && return 0
    echo "scripts/test.sh: installing chromium and chromium-driver (the HTML report tests)" >&2
    if ! apt_install --no-install-recommends chromium chromium-driver; then
        echo "scripts/test.sh: NOTE: could not install chromium; the browser tests will say SKIPPED (and fail under CI=true)" >&2
    fi
}

pyvenv=target/python-venv
# Everything the tests need beside the build: the Vulkan driver, the browser, OpenCV (the Harris /
# Shi-Tomasi agreement test), and the Python package's build tool (its metadata check) and test tools
# (rosbags: the ROS bag example, no ROS install needed; the ROS 2 Jazzy wheels: the map_merge node's
# tests, its `ros` extra; Ray: the distributed engine's test on a local Ray instance, its `ray` extra).
set_up() {
    install_vulkan
    install_browser
    python_env target/opencv-venv "import cv2, numpy" opencv-python-headless numpy
    python_env "$pyvenv" "import maturin, numpy, pytest, rosbags, rclpy, nav_msgs.msg, geometry_msgs.msg, ray" \
        "maturin>=1.9.4,<2" numpy pytest rosbags \
        ros-jazzy-rclpy ros-jazzy-nav-msgs ros-jazzy-geometry-msgs ros-jazzy-rmw-fastrtps-cpp \
        "ray>=2.9"
}

# The set-up runs in the background beside the build: its downloads and unpacking take minutes on a fresh
# machine and need little of the CPU the compiler uses. Its output is printed once it ends; a password
# sudo needs is asked for first, here, not from the background. A build that fails still waits for it,
# so no install is left half done.
if [ "$(id -u)" != 0 ] && ! { have_vulkan && have_browser; }; then sudo -v; fi
mkdir -p target
setup_log=target/test-setup.log
set_up >"$setup_log" 2>&1 &
setup_pid=$!
trap 'wait "$setup_pid" 2>/dev/null || true' EXIT

# Unit, integration and doc tests, and the Python extension, in one build: with the same dependency graph
# (feature unification spans the selected packages) the extension costs only itself. The extension links
# no libpython, as maturin builds it (PYO3_BUILD_EXTENSION_MODULE). The dev profile is optimised
# (Cargo.toml), so real maps stay quick.
export PYO3_BUILD_EXTENSION_MODULE=1
cargo build --locked --workspace --lib --bins --tests --examples
phase "built"
setup_status=0
wait "$setup_pid" || setup_status=$?
cat "$setup_log" >&2
if [ "$setup_status" != 0 ]; then
    echo "scripts/test.sh: setting up the test environment failed (above)" >&2
    exit 1
fi
phase "set up: Vulkan driver, browser, Python environments"
cargo test --locked --workspace
phase "Rust tests passed"

# The runnable examples (examples/), on the demo's robot maps; then the API documentation, warnings as
# errors (every public item documented, no broken link).
ex=target/examples-run
rm -rf "$ex" && mkdir -p "$ex/maps"
target/debug/ogm-corners demo -o "$ex" >/dev/null 2>&1 || { echo "scripts/test.sh: demo failed" >&2; exit 1; }
cp "$ex"/robot-*.yaml "$ex"/robot-*.pgm "$ex/maps/"
# Run as built above: `cargo run --example` selects the core crate alone, whose dependencies then have
# fewer features unified (the extension's numpy adds some), so it would build the crate a second time.
target/debug/examples/detect_map "$ex/maps/robot-1.yaml" >/dev/null
target/debug/examples/merge_two "$ex/maps/robot-1.yaml" "$ex/maps/robot-2.yaml" "$ex/two.yaml" >/dev/null
target/debug/examples/merge_folder "$ex/maps" "$ex/all.yaml" >/dev/null
target/debug/examples/device_map "$ex/maps/robot-1.yaml" >/dev/null
[ -f "$ex/two.yaml" ] && [ -f "$ex/all.yaml" ] || { echo "scripts/test.sh: an example wrote no merged map" >&2; exit 1; }
echo "scripts/test.sh: examples detect_map, merge_two, merge_folder, device_map ran"
# The whole workspace, for the same reason: its dependencies checked as the lints checked them.
RUSTDOCFLAGS="-D warnings" cargo doc --locked --no-deps --workspace -q
phase "examples ran, API documentation built"

# The Python package: the extension placed in python/ogm_corners/ as `maturin develop` places it, the
# package's metadata checked by making its source distribution (`pip install ./python` builds the same
# crate in release), then its tests, which compare it with the binary built above.
cp target/debug/lib_core.so python/ogm_corners/_core.abi3.so
(cd python && "../$pyvenv/bin/maturin" sdist --out ../target/sdist >/dev/null 2>&1) || {
    echo "scripts/test.sh: maturin could not make the Python package's source distribution" >&2
    exit 1
}
PYTHONPATH="$PWD/python" OGM_CORNERS_BIN="$PWD/target/debug/ogm-corners" \
    "$pyvenv/bin/python" -m pytest python/tests -q -p no:cacheprovider
phase "Python tests passed"

# The HTML reports (`--html DIR`) in a real browser: headless Chromium loads each page from file://, the
# tables' row counts are checked against the command's JSON, every picture must load, a column is sorted
# by a click; screenshots go to target/browser/.
OGM_CORNERS_BIN="$PWD/target/debug/ogm-corners" \
    "$pyvenv/bin/python" -m pytest tests/browser -q -p no:cacheprovider
phase "browser tests passed; all done"
