"""What the Python package adds over the Rust library (a benchmark, not a test).

1. Per-call overhead on a 1024 x 1024 map: the median of ``Detector.detect`` from Python (a ``Map``, a
   numpy array read in place, and the ``detect()`` function with its cached detector) against the Rust
   call timed inside the extension (``Detector._time_rust``: the library's detect alone), all in turn in
   one process; and the tool's own ``bench`` of the same map, in its own process, for reference.
2. The rclpy path on a 4096 x 4096 map: ``nav_msgs/OccupancyGrid`` data as rclpy delivers it
   (``array('b')``), as a plain list of ints, and as an int8 numpy array, to keypoints.

Usage (a release build of both, the same machine, nothing else running):

    cargo build --release && (cd python && maturin develop --release)
    python python/benches/overhead.py --cli target/release/ogm-corners [--repeat 201]
"""

from __future__ import annotations

import argparse
import array
import json
import os
import platform
import statistics
import subprocess
import tempfile
import time
from typing import Callable, Dict, List

import ogm_corners as oc


def median_ms(f: Callable[[], object], repeat: int) -> float:
    f()  # warm-up: first-use costs stay out of the median
    times: List[float] = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times) * 1e3


def interleaved_medians_ms(calls: Dict[str, Callable[[], object]], repeat: int) -> Dict[str, float]:
    """The calls timed in turn, round after round, so that the machine's drift (clock, caches, other
    processes) falls on all of them alike."""
    for f in calls.values():
        f()
    times: Dict[str, List[float]] = {k: [] for k in calls}
    for _ in range(repeat):
        for k, f in calls.items():
            t = time.perf_counter()
            f()
            times[k].append(time.perf_counter() - t)
    return {k: statistics.median(v) * 1e3 for k, v in times.items()}


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def rust_median_ms(cli: str, path: str, repeat: int) -> float:
    out = subprocess.run(
        [cli, "bench", path, "--detector", "ogm", "--backend", "cpu", "--repeat", str(repeat),
         "--format", "json"],
        capture_output=True, text=True, check=True,
    ).stdout
    records = json.loads(out)
    records = records["records"] if isinstance(records, dict) else records
    return next(r["median_ms"] for r in records if r["stage"] == "end_to_end")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", required=True, help="a release build of ogm-corners")
    ap.add_argument("--repeat", type=int, default=201, help="calls timed at 1024^2 (21 at most at 4096^2)")
    args = ap.parse_args()
    print(f"machine: {cpu_model()}, {os.cpu_count()} threads; ogm-corners {oc.__version__}; "
          f"medians of {args.repeat}")

    m = oc.synthetic.office(1024, 1024, seed=1)
    d = oc.Detector("ogm", "cpu")
    n = len(d.detect(m))
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "office.yaml")
        m.save(path)
        rust = rust_median_ms(args.cli, path, args.repeat)
    px = m.pixels
    inside: List[float] = []
    calls = {
        "Rust call, timed inside the extension": lambda: inside.append(d._d._time_rust(m._m)),
        "`Detector.detect(map)`": lambda: d.detect(m),
        "`Detector.detect(array)` (in place)": lambda: d.detect(px),
        "`detect(map, backend=\"cpu\")`": lambda: oc.detect(m, backend="cpu"),
    }
    medians = interleaved_medians_ms(calls, args.repeat)
    base = statistics.median(inside) * 1e3
    del medians["Rust call, timed inside the extension"]
    rows = [("Rust call (the library's detect, timed inside the extension)", base)] + list(
        medians.items()
    )
    print(f"\n1024 x 1024 office map, OGM detector, fast CPU path, {n} keypoints\n")
    print("| call | median | over the Rust call |")
    print("|---|---|---|")
    for name, ms in rows:
        over = "" if ms is base else f"{(ms - base) * 1e3:+.0f} us"
        print(f"| {name} | {ms:.3f} ms | {over} |")
    print(f"| `ogm-corners bench` (its own process) | {rust:.3f} ms | |")

    big = oc.synthetic.office(4096, 4096, seed=1)
    g = big.to_occupancy_grid()
    as_array = array.array("b", g.data.tobytes())
    as_list = g.data.tolist()
    cells = g.data.reshape(g.height, g.width)
    mpx = g.width * g.height / 1e6
    d4 = oc.Detector("ogm", "cpu")
    n4 = len(d4.detect(big))

    def from_grid(data: object) -> Callable[[], object]:
        return lambda: d4.detect(
            oc.Map.from_occupancy_grid(data, g.width, g.height, g.resolution, g.origin)
        )

    rep = min(args.repeat, 21)
    rows = [
        ("`Detector.detect(map)` (the map already built)", median_ms(lambda: d4.detect(big), rep)),
        ("`array('b')` (rclpy's `msg.data`) -> `Map.from_occupancy_grid` -> detect",
         median_ms(from_grid(as_array), rep)),
        ("int8 numpy -> `Map.from_occupancy_grid` -> detect", median_ms(from_grid(g.data), rep)),
        ("int8 numpy (H, W) -> `detect` in place (grid rows as given)",
         median_ms(lambda: d4.detect(cells), rep)),
        ("list of ints -> `Map.from_occupancy_grid` -> detect", median_ms(from_grid(as_list), 5)),
    ]
    print(f"\n4096 x 4096 office map as a nav_msgs/OccupancyGrid, OGM detector, fast CPU path, {n4} keypoints\n")
    print("| path | median | Mpx/s |")
    print("|---|---|---|")
    for name, ms in rows:
        print(f"| {name} | {ms:.1f} ms | {mpx / (ms / 1e3):.0f} |")


if __name__ == "__main__":
    main()
