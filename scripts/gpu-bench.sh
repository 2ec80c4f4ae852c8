#!/usr/bin/env bash
# The GPU check on a machine with a real GPU, in one command and under 5 minutes: the Vulkan loader, the
# adapter, CPU = GPU on real maps and every synthetic size (bench fails when any backend's keypoints differ
# from the others'), the bench stages (kernel_resident, upload, upload_ref, transfer_floor, end_to_end, with
# the write passes and dispatches a map took; device_map, the map already in a device buffer) at 4096^2,
# 16384^2 and 65536^2, and the conformance tests when their binary is given. Everything goes to one folder.
#
#   scripts/gpu-bench.sh [OUT_DIR] [MAP_DIR...]
#
# OUT_DIR defaults to target/gpu-bench. MAP_DIRs (real maps) are optional; ../shared/maps is used when it
# exists. Environment:
#   OGM_BIN               a prebuilt ogm-corners (else cargo build --release)
#   OGM_CONFORMANCE_BIN   a prebuilt backends' test binary (cargo test --no-run --test backend); its
#                         GPU tests (gpu_conformance, gpu_device_map) are run
#   OGM_PEAK_BANDWIDTH    the GPU's peak memory bandwidth, GB/s, when bench does not know the adapter
#   OGM_BIG               set to 0 to leave out the 65536^2 map (4 GiB of host memory, 4 GiB on the GPU)
#   OGM_SIZES             the other synthetic sizes (default "4096x4096 16384x16384")
#   OGM_TUNE              set to 0 to leave out the tuning runs (strips of 4, 8 and 16 rows; bands copied)
set -uo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/gpu-bench}
shift || true
mkdir -p "$out"
log() { echo "gpu-bench: $*" | tee -a "$out/summary.txt" >&2; }
: >"$out/summary.txt"

# The Vulkan loader, and glvnd's dispatch library that NVIDIA's Vulkan driver (libGLX_nvidia) loads: unpack
# carried packages (see the device notes) when the system lacks either. Without libGLdispatch the loader
# finds the driver's manifest but no adapter.
has_lib() { ldconfig -p 2>/dev/null | grep "$1" >/dev/null; }
if ! has_lib 'libvulkan\.so\.1' || { [ -e /usr/local/nvidia ] && ! has_lib 'libGLdispatch\.so\.0'; }; then
    if compgen -G ".gl/*.deb" >/dev/null; then
        for f in .gl/*.deb; do dpkg -x "$f" /; done
        ldconfig
    fi
fi
if ! has_lib 'libvulkan\.so\.1'; then
    log "no Vulkan loader (libvulkan.so.1): install libvulkan1 or carry it in .gl/"
    exit 1
fi
if [ -e /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ] && [ -z "${VK_DRIVER_FILES:-}" ]; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
fi
# wgpu must find the hardware adapter, not a software one.
export WGPU_BACKEND=${WGPU_BACKEND:-vulkan}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}

bin=${OGM_BIN:-}
if [ -z "$bin" ]; then
    cargo build --release --locked >/dev/null || { log "cargo build failed"; exit 1; }
    bin=target/release/ogm-corners
fi
{ nvidia-smi 2>&1 || true; } >"$out/nvidia-smi.txt"
{ command -v vulkaninfo >/dev/null && vulkaninfo 2>&1 | grep -iE -A3 'memoryHeaps|memoryTypes|deviceName|driverVersion|subgroupSize' | head -200; } >"$out/vulkan-memory.txt" 2>&1 || true
"$bin" info >"$out/info.txt" 2>&1
log "adapter: $(grep -m1 -i 'gpu\|adapter' "$out/info.txt" || echo unknown)"
if grep -qi 'llvmpipe\|lavapipe\|swiftshader' "$out/info.txt" && [ -z "${OGM_ALLOW_SOFTWARE:-}" ]; then
    log "only a software adapter was found; set OGM_ALLOW_SOFTWARE=1 to measure it anyway"
    exit 1
fi

peak=()
[ -n "${OGM_PEAK_BANDWIDTH:-}" ] && peak=(--peak-bandwidth "$OGM_PEAK_BANDWIDTH")
status=0
run() {
    local name=$1
    shift
    local t0=$SECONDS
    if timeout 240 "$bin" "$@" >"$out/$name.txt" 2>"$out/$name.err"; then
        log "$name: ok ($((SECONDS - t0)) s)"
    else
        log "$name: FAILED ($((SECONDS - t0)) s; see $name.err)"
        status=1
    fi
}

# CPU = GPU on the real maps, every detector (bench compares every backend's keypoints).
maps=("$@")
[ ${#maps[@]} -eq 0 ] && [ -d ../shared/maps ] && maps=(../shared/maps)
if [ ${#maps[@]} -gt 0 ]; then
    run real-maps bench --backend cpu,gpu --detector all --repeat 3 "${peak[@]}" "${maps[@]}"
else
    log "real-maps: no map folder given and ../shared/maps not found; skipped"
fi
# The stages on synthetic maps; the CPU rows double as the equality check.
sizes=()
for s in ${OGM_SIZES:-4096x4096 16384x16384}; do sizes+=(--size "$s"); done
run synthetic-ogm bench --backend cpu,gpu --detector ogm --repeat 10 "${peak[@]}" "${sizes[@]}"
run synthetic-baselines bench --backend cpu,gpu --detector harris,shi-tomasi,trajkovic --repeat 3 \
    "${peak[@]}" "${sizes[@]}"
# Tuning, each against the defaults above: the strip height (the backend takes 16 rows, or 8 or 4 where a
# small map would leave the GPU short of workgroups) and reading staged bands in place against copying
# them into device buffers first. The adapter's label in each file says what was set.
if [ "${OGM_TUNE:-1}" != 0 ]; then
    for rows in 4 8 16; do
        run "tune-strip-$rows" bench --backend gpu --detector ogm --repeat 5 --gpu-strip-rows "$rows" \
            "${peak[@]}" "${sizes[@]}"
    done
    run tune-copy-bands bench --backend gpu --detector ogm --repeat 5 --gpu-copy-bands "${peak[@]}" "${sizes[@]}"
fi
if [ "${OGM_BIG:-1}" != 0 ]; then
    run synthetic-65536 bench --backend cpu,gpu --detector ogm --repeat 3 "${peak[@]}" --size 65536x65536
fi
if [ -n "${OGM_CONFORMANCE_BIN:-}" ]; then
    t0=$SECONDS
    # Not CI=true: that also demands the merge-pairs data, which need not be here. The adapter was checked
    # above, so no GPU test can skip for want of one; the real-map tests read the first map folder.
    envs=()
    [ -n "${maps[0]:-}" ] && envs=(OGM_MAPS_DIR="${maps[0]}")
    if env "${envs[@]}" timeout 240 "$OGM_CONFORMANCE_BIN" gpu_ --test-threads 4 >"$out/conformance.txt" 2>&1; then
        log "conformance: ok ($((SECONDS - t0)) s)"
    else
        log "conformance: FAILED ($((SECONDS - t0)) s; see conformance.txt)"
        status=1
    fi
fi
# The figures in one place: every GPU row and the CPU rows beside them.
for f in "$out"/synthetic-*.txt "$out"/tune-*.txt; do
    [ -f "$f" ] || continue
    echo "## $(basename "$f" .txt)"
    grep -hE '^# (backends|gpu)|^map |  gpu  |  cpu  ' "$f"
done >"$out/figures.txt" 2>/dev/null || true
log "done: $out (status $status)"
exit $status
