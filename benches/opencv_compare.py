#!/usr/bin/env python3
"""Throughput of ogm-corners' fast CPU path against OpenCV on the same pixels, as one markdown table.

Usage: benches/opencv_compare.py [--sizes 1024,4096,16384] [--no-shared] [--maps DIR] [--repeat N]
                                 [--seed N] [--bin PATH] [--json OUT]

For each synthetic office map (written by `ogm-corners bench --save-map`, so both sides read identical
pixels) and each shared real map (../shared/maps beside the project, or $OGM_MAPS_DIR, or --maps; said
clearly when absent), times:

- ours: `ogm-corners bench --backend cpu --detector all --format json` (end to end: image in memory to
  keypoints in memory; median of N runs after a warm-up), from a release build (built here unless --bin);
- OpenCV, with all threads (cv2.setNumThreads), median of N runs after a warm-up:
  - FAST: cv2.FastFeatureDetector_create() with its defaults, detect() on the map;
  - Harris: GaussianBlur(3x3, sigma 1) + cornerHarris(blockSize 3, ksize 3, k 0.04) + selection
    (response > 0.01 x max, response == 3x3 dilate, np.nonzero);
  - Shi-Tomasi: GaussianBlur(3x3, sigma 1) + goodFeaturesToTrack(maxCorners 0, qualityLevel 0.01,
    minDistance 3, blockSize 3).

Pairs: ogm vs FAST, harris vs blur + cornerHarris + selection, shi-tomasi vs blur + goodFeaturesToTrack,
trajkovic vs FAST. Ratio = our Mpx/s over OpenCV's (above 1: ours is faster).

Needs python3 with cv2 and numpy; when they are missing here, the script re-runs itself with
target/opencv-venv/bin/python (scripts/test.sh creates that environment).
"""
import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENV_PY = os.path.join(ROOT, "target", "opencv-venv", "bin", "python")

try:
    import cv2
    import numpy as np
except ImportError:
    # The venv's python is a symlink to the system one, so compare prefixes, not executables.
    if os.path.exists(VENV_PY) and os.path.realpath(sys.prefix) != os.path.realpath(os.path.dirname(os.path.dirname(VENV_PY))):
        os.execv(VENV_PY, [VENV_PY, os.path.abspath(__file__), *sys.argv[1:]])
    sys.exit(
        "opencv_compare.py: needs cv2 and numpy: run scripts/test.sh once (it creates "
        "target/opencv-venv) or pip install opencv-python-headless numpy"
    )

# (our detector, OpenCV counterpart); the counterparts are timed once per map.
PAIRS = [
    ("ogm", "FAST"),
    ("harris", "GaussianBlur+cornerHarris+selection"),
    ("shi-tomasi", "GaussianBlur+goodFeaturesToTrack"),
    ("trajkovic", "FAST"),
]


def log(msg):
    print(f"opencv_compare: {msg}", file=sys.stderr, flush=True)


def parse_sizes(text):
    """'1024,4096' or '1024x768,4096' -> [(w, h), ...]."""
    sizes = []
    for part in text.split(","):
        part = part.strip().lower()
        if not part:
            continue
        w, _, h = part.partition("x")
        sizes.append((int(w), int(h or w)))
    return sizes


def find_binary(path):
    if path:
        return path
    log("building the release binary (cargo build --release)")
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    return os.path.join(target, "release", "ogm-corners")


def run_ours(binary, args, repeat):
    """Runs `ogm-corners bench ... --backend cpu --detector all --format json`; returns the report."""
    cmd = [binary, "bench", *args, "--backend", "cpu", "--detector", "all", "--format", "json",
           "--repeat", str(repeat)]
    log(" ".join(cmd))
    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE).stdout
    return json.loads(out)


def load_grey(path):
    """The 8-bit grey pixels ogm-corners detects on: 16-bit scaled to 8, colour to luminance."""
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise SystemExit(f"opencv_compare.py: {path}: OpenCV cannot read it")
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code)
    return np.ascontiguousarray(img)


def fast(img):
    return len(cv2.FastFeatureDetector_create().detect(img))


def harris(img):
    blur = cv2.GaussianBlur(img, (3, 3), 1)
    r = cv2.cornerHarris(blur, 3, 3, 0.04)
    keep = (r > 0.01 * r.max()) & (r == cv2.dilate(r, None))
    ys, _ = np.nonzero(keep)
    return len(ys)


def shi_tomasi(img):
    blur = cv2.GaussianBlur(img, (3, 3), 1)
    pts = cv2.goodFeaturesToTrack(blur, maxCorners=0, qualityLevel=0.01, minDistance=3, blockSize=3)
    return 0 if pts is None else len(pts)


COUNTERPARTS = {
    "FAST": fast,
    "GaussianBlur+cornerHarris+selection": harris,
    "GaussianBlur+goodFeaturesToTrack": shi_tomasi,
}


def time_opencv(fn, img, repeat):
    """(median ms, keypoints) of `repeat` runs after one warm-up."""
    n = fn(img)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn(img)
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times), n


def compare_map(label, image_path, ours, repeat):
    """Rows for one map: `ours` maps our detector to its end-to-end record."""
    img = load_grey(image_path)
    h, w = img.shape
    mpx = w * h / 1e6
    cv = {}
    for name, fn in COUNTERPARTS.items():
        log(f"OpenCV {name} on {label} {w}x{h}")
        cv[name] = time_opencv(fn, img, repeat)
    rows = []
    for det, other in PAIRS:
        rec = ours.get(det)
        if rec is None:
            continue
        if (rec["width"], rec["height"]) != (w, h):
            raise SystemExit(f"opencv_compare.py: {image_path}: OpenCV reads {w}x{h}, ogm-corners "
                             f"{rec['width']}x{rec['height']}")
        cv_ms, cv_n = cv[other]
        cv_mpx_s = mpx / (cv_ms / 1e3)
        rows.append({
            "map": label, "width": w, "height": h, "image": image_path,
            "detector": det, "ours_ms": rec["median_ms"], "ours_mpx_per_s": rec["mpx_per_s"],
            "ours_keypoints": rec["keypoints"],
            "opencv": other, "opencv_ms": cv_ms, "opencv_mpx_per_s": cv_mpx_s, "opencv_keypoints": cv_n,
            "ratio": rec["mpx_per_s"] / cv_mpx_s,
        })
    return rows


def end_to_end(records):
    """{(source or image, detector): record} for the cpu backend's end-to-end records."""
    out = {}
    for r in records:
        if r["backend"] == "cpu" and r["stage"] == "end_to_end":
            out.setdefault(r["source"] or r["image"], {})[r["detector"]] = r
    return out


def shared_maps_dir(arg):
    if arg:
        return arg
    return os.environ.get("OGM_MAPS_DIR") or os.path.join(ROOT, "..", "shared", "maps")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1024,4096,16384",
                    help="synthetic map sides, comma-separated: N for NxN or WxH (default 1024,4096,16384)")
    ap.add_argument("--no-shared", action="store_true", help="leave out the shared real maps")
    ap.add_argument("--maps", help="folder of real maps (default $OGM_MAPS_DIR or ../shared/maps)")
    ap.add_argument("--repeat", type=int, default=10, help="timed runs per measurement (default 10)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the synthetic maps (default 1)")
    ap.add_argument("--bin", help="the ogm-corners binary (default: build target/release/ogm-corners)")
    ap.add_argument("--json", metavar="OUT", help="also write every row (with times and counts) as JSON")
    a = ap.parse_args()
    if a.repeat < 1:
        ap.error("--repeat must be at least 1")
    sizes = parse_sizes(a.sizes)
    binary = find_binary(a.bin)
    cv2.setNumThreads(os.cpu_count() or 1)  # all threads

    rows, notes, report = [], [], None
    with tempfile.TemporaryDirectory(prefix="ogm-opencv-") as tmp:
        for w, h in sizes:
            pgm = os.path.join(tmp, f"synthetic-{w}x{h}.pgm")
            report = run_ours(binary, ["--size", f"{w}x{h}", "--seed", str(a.seed), "--save-map", pgm],
                              a.repeat)
            ours = end_to_end(report["records"]).get(pgm, {})
            rows += compare_map("synthetic", pgm, ours, a.repeat)
            os.remove(pgm)  # 16384^2 is 268 MB
    if a.no_shared:
        notes.append("Shared real maps: left out (--no-shared).")
    else:
        d = shared_maps_dir(a.maps)
        if os.path.isdir(d):
            report = run_ours(binary, [d], a.repeat)
            for key, ours in end_to_end(report["records"]).items():
                any_rec = next(iter(ours.values()))
                rows += compare_map(any_rec["map"], any_rec["image"], ours, a.repeat)
        else:
            msg = f"Shared real maps: NOT FOUND at {os.path.normpath(d)}; no real-map rows."
            log(msg)
            notes.append(msg)
    if report is None:
        report = run_ours(binary, ["--size", "64x64"], 1)  # only for the machine and commit

    header = (f"Machine: {report['cpu']} ({report['threads']} threads), {report['os']} {report['arch']}; "
              f"date {datetime.datetime.now().astimezone().isoformat(timespec='minutes')}; "
              f"ogm-corners {report['version']} (git {report['commit']}); OpenCV {cv2.__version__} "
              f"on {cv2.getNumThreads()} threads; medians of {a.repeat} runs after a warm-up; "
              f"ratio = ours / OpenCV (above 1: ours is faster).")
    print(header)
    print()
    print("| map | size | our detector | our Mpx/s | OpenCV counterpart | OpenCV Mpx/s | ratio |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['map']} | {r['width']}x{r['height']} | {r['detector']} | {r['ours_mpx_per_s']:.1f} "
              f"| {r['opencv']} | {r['opencv_mpx_per_s']:.1f} | {r['ratio']:.2f} |")
    for n in notes:
        print()
        print(n)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"header": header, "opencv": cv2.__version__, "notes": notes, "rows": rows}, f,
                      indent=2)
        log(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
