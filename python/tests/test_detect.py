"""Detection from Python: the same keypoints as the command-line tool, every input kind, bad input."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest

import ogm_corners as oc

from conftest import CI, missing, run_cli

# Every detector, with an option of its own so options are seen to reach the library.
CASES = [
    ("ogm", {}, []),
    ("ogm", {"rules": "paper-mod2", "unknown_as_occupied": True},
     ["--rules", "paper-mod2", "--unknown-as-occupied"]),
    ("ogm-robust", {"min_strength": 6}, ["--min-strength", "6"]),
    ("ogm-robust", {"cell_occupied": 9, "cell_free": 30, "wall_gap": 3},
     ["--cell-occupied", "9", "--cell-free", "30", "--wall-gap", "3"]),
    ("ogm-robust", {"anchor": "centre"}, ["--anchor", "centre"]),
    ("ogm-robust", {"anchor": (12.5, -3.0)}, ["--anchor", "12.5,-3"]),
    ("harris", {"max_corners": 300}, ["--max-corners", "300"]),
    ("shi-tomasi", {"min_distance": 5.0}, ["--min-distance", "5"]),
    ("trajkovic", {}, []),
]


def cli_keypoints(cli, path, tmp_path, detector, args):
    out = tmp_path / "kp.json"
    r = run_cli(cli, "detect", path, "--detector", detector, "--backend", "cpu",
                "--format", "json", "-o", out, *args)
    assert r.returncode == 0, r.stderr
    return json.loads(out.read_text())


def assert_same(doc, kp):
    """The CLI's JSON keypoints and the package's, field by field."""
    assert doc["count"] == len(kp)
    got = kp.array
    want = doc["keypoints"]
    assert [k["x"] for k in want] == got["x"].tolist()
    assert [k["y"] for k in want] == got["y"].tolist()
    for field in ("rule", "code", "score", "scale", "convex"):
        if want and field in want[0]:
            assert [k[field] for k in want] == got[field].tolist(), field
    if want and "world" in want[0]:
        assert kp.has_world
        np.testing.assert_array_equal(np.array([k["world"] for k in want]), kp.world)
    if "angle_deg" in doc:
        assert kp.angle == doc["angle_deg"]


@pytest.mark.parametrize("detector,options,args", CASES)
def test_same_keypoints_as_the_cli_on_a_synthetic_map(cli, office_files, tmp_path, detector, options, args):
    doc = cli_keypoints(cli, office_files, tmp_path, detector, args)
    kp = oc.detect(oc.load_map(office_files), detector=detector, backend="cpu", **options)
    assert len(kp) > 0
    assert_same(doc, kp)


@pytest.mark.parametrize("detector,options,args", CASES[:1] + CASES[2:])
def test_same_keypoints_as_the_cli_on_the_shared_maps(cli, shared_maps, tmp_path, detector, options, args):
    d = oc.Detector(detector, "cpu", **options)
    for path in shared_maps:
        doc = cli_keypoints(cli, path, tmp_path, detector, args)
        assert_same(doc, d.detect(path))


def test_a_map_that_grows_at_its_edges_keeps_its_robust_keypoints(office):
    """A SLAM map grows and its origin moves with it: the robust detector's grid is anchored at the world
    frame's origin, so with the angle of the first detection the corners found before are found again,
    the same, at their pixels in the grown map."""
    turned = oc.synthetic.robot_maps(office, 2, seed=3)[0][0]
    res = turned.resolution
    first = oc.detect(turned, detector="ogm-robust", backend="cpu")
    assert len(first) > 20 and first.angle not in (0.0, None)
    # 37 unknown columns on the left, 11 on the right, 23 rows on top, 5 below: the origin (the lower
    # left corner) moves 37 pixels left and 5 down.
    px = np.pad(turned.pixels, ((23, 5), (37, 11)), constant_values=205)
    ox, oy, yaw = turned.origin
    grown = oc.Map(px, res, (ox - 37 * res, oy - 5 * res, yaw))
    again = oc.detect(grown, detector="ogm-robust", backend="cpu", angle=first.angle)
    h, w = turned.pixels.shape

    def inside(a, x0, y0):
        # A corner placed outside the map is clamped onto its edge, which the grown map does not have.
        return (a["x"] > x0) & (a["y"] > y0) & (a["x"] < x0 + w - 1) & (a["y"] < y0 + h - 1)

    was, now = inside(first.array, 0, 0), inside(again.array, 37, 23)
    want, got = first.array[was].copy(), again.array[now]
    want["x"] += 37
    want["y"] += 23
    assert len(got) == len(want) > 20
    for field in ("x", "y", "score", "scale", "convex", "rule", "code"):
        np.testing.assert_array_equal(got[field], want[field], field)
    # The same places in the world.
    np.testing.assert_allclose(again.world[now], first.world[was], atol=1e-9)


def test_world_coordinates_follow_ros(office):
    kp = oc.detect(office, backend="cpu")
    assert kp.has_world
    wx, wy = office.pixel_to_world(kp.x, kp.y)
    np.testing.assert_allclose(kp.world, np.column_stack((wx, wy)), rtol=0, atol=1e-12)
    # Row 0 is the top: the top row's cell centres are the highest in the world.
    assert office.pixel_to_world(0, 0)[1] == pytest.approx((office.height - 0.5) * office.resolution)


def test_arrays_are_read_in_place_and_strided_views_copied(office):
    px = np.array(office.pixels)  # writable, C-contiguous
    ref = oc.detect(office, backend="cpu")
    a = oc.detect(px, backend="cpu")
    assert not a.has_world
    np.testing.assert_array_equal(a.xy, ref.xy)
    # A transposed (Fortran-ordered) view: a copy, and keypoints indexing the view as given.
    t = oc.detect(px.T, backend="cpu")
    np.testing.assert_array_equal(np.sort(t.xy[:, ::-1], axis=0), np.sort(oc.detect(np.ascontiguousarray(px.T), backend="cpu").xy[:, ::-1], axis=0))
    # A strided sub-view equals the same window copied.
    v = px[1::1, 3:-2]
    np.testing.assert_array_equal(oc.detect(v, backend="cpu").xy, oc.detect(v.copy(), backend="cpu").xy)
    # Map(copy=False) reads the array in place: a later write shows.
    shared = oc.Map(px, copy=False)
    copied = oc.Map(px)
    px[:] = 254
    assert shared.pixels.max() == 254 and shared.pixels.min() == 254
    assert copied.pixels.min() == 0


def test_pixels_are_a_read_only_view(office):
    p = office.pixels
    assert p.shape == office.shape and p.dtype == np.uint8
    assert not p.flags.writeable
    with pytest.raises(ValueError):
        p[0, 0] = 1
    # No copy: two views share memory.
    assert np.shares_memory(office.pixels, office.pixels)
    del office  # the view keeps the map alive
    assert int(p.sum()) > 0


def test_states(office):
    s = office.states()
    px = office.pixels
    assert set(np.unique(s)) <= {oc.State.FREE, oc.State.UNKNOWN, oc.State.OCCUPIED}
    assert (s[px == 0] == oc.State.OCCUPIED).all()
    assert (s[px == 254] == oc.State.FREE).all()
    assert (s[px == 205] == oc.State.UNKNOWN).all()


def test_int8_grid_arrays_are_read_as_map_saver_reads_them(office):
    g = office.to_occupancy_grid()
    cells = g.data.reshape(g.height, g.width)  # row 0 at the bottom, as ROS has it
    kp = oc.detect(cells, backend="cpu")
    ref = oc.detect(office, backend="cpu")
    # The grid is the image upside down: its keypoints index the grid's rows.
    np.testing.assert_array_equal(np.sort(kp.y), np.sort(office.height - 1 - ref.y))
    # Intermediate probabilities: thresholds as map_saver (free <= 25, occupied >= 65).
    noisy = cells.copy()
    noisy[noisy == 0] = 20
    noisy[noisy == 100] = 70
    np.testing.assert_array_equal(oc.detect(noisy, backend="cpu").xy, kp.xy)
    # The baselines read the states drawn as map_server draws them.
    h1 = oc.detect(cells, detector="harris", backend="cpu")
    h2 = oc.detect(np.ascontiguousarray(office.pixels[::-1]), detector="harris", backend="cpu")
    np.testing.assert_array_equal(h1.array, h2.array)


def test_detector_keeps_its_backend_and_reports_it(office):
    d = oc.Detector("ogm-robust", "cpu", max_corners=10)
    assert d.detector == "ogm-robust" and d.backend == "cpu"
    kp = d.detect(office)
    assert len(kp) == 10 and kp.angle is not None
    assert (np.diff(kp.y.astype(np.int64)) >= 0).all()  # sorted by (y, x)
    assert "ogm-robust" in repr(kp) and len(kp[kp.score > 0]) == 10
    assert isinstance(kp[0], np.void) and kp["x"].dtype == np.uint32


def test_gpu_backend_gives_the_cpu_keypoints(office):
    try:
        d = oc.Detector("ogm", "gpu")
    except oc.BackendUnavailableError as e:
        missing(f"no GPU adapter (install mesa-vulkan-drivers for lavapipe): {e}")
    np.testing.assert_array_equal(d.detect(office).array, oc.detect(office, backend="reference").array)


@pytest.mark.parametrize(
    "call,message",
    [
        (lambda: oc.detect(np.zeros((0, 5), np.uint8)), "zero-size map"),
        (lambda: oc.detect(np.zeros(5, np.uint8)), "2-D"),
        (lambda: oc.detect(np.zeros((5, 5), np.float32)), "uint8"),
        (lambda: oc.detect(np.zeros((5, 5), np.uint8), detector="sift"), "unknown detector `sift`"),
        (lambda: oc.detect(np.zeros((5, 5), np.uint8), backend="tpu"), "unknown backend `tpu`"),
        (lambda: oc.detect(np.zeros((5, 5), np.uint8), rules="mod5"), "unknown rules"),
        (lambda: oc.detect(np.zeros((5, 5), np.uint8), colour=3), "colour"),
        (lambda: oc.detect(np.full((64, 64), 254, np.uint8), detector="ogm-robust", min_scale=9,
                           max_scale=3, backend="cpu"), "scale"),
        (lambda: oc.detect(np.full((64, 64), 254, np.uint8), detector="ogm-robust", cell_occupied=0,
                           backend="cpu"), "occupied share"),
        (lambda: oc.detect(np.full((64, 64), 254, np.uint8), detector="ogm-robust", wall_gap=100,
                           backend="cpu"), "wall gap"),
        (lambda: oc.detect(np.full((64, 64), 254, np.uint8), detector="ogm-robust", anchor="middle",
                           backend="cpu"), "unknown anchor"),
        (lambda: oc.detect(np.full((64, 64), 254, np.uint8), detector="ogm-robust", anchor=(1e7, 0.0),
                           backend="cpu"), "grid anchor"),
        (lambda: oc.Detector("harris", "cpu", sigma=-1.0).detect(np.full((9, 9), 254, np.uint8)), "sigma"),
        (lambda: oc.Map(np.zeros((4, 4), np.int8)), "from_occupancy_grid"),
        (lambda: oc.Map(np.zeros((4, 4), np.uint8), resolution=0.0), "resolution"),
        (lambda: oc.Map(np.zeros((4, 4), np.uint8), occupied_thresh=2.0), "occupied_thresh"),
        (lambda: oc.load_map("/nonexistent/map.yaml"), "no such map"),
    ],
)
def test_bad_input_raises_one_line_python_errors(call, message):
    with pytest.raises((ValueError, TypeError, FileNotFoundError)) as e:
        call()
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test_bad_map_file_has_the_cli_message(cli, tmp_path):
    bad = tmp_path / "bad.pgm"
    bad.write_bytes(b"P5\n4 4\n255\n\x00")  # truncated raster
    r = run_cli(cli, "detect", bad)
    assert r.returncode == 2
    with pytest.raises(ValueError) as e:
        oc.load_map(bad)
    assert str(e.value) in r.stderr


def test_the_gil_is_released_during_detection():
    # A long detection on the single-threaded reference; the main thread counts while it runs.
    big = oc.synthetic.office(3000, 3000, seed=1)
    d = oc.Detector("harris", "reference")
    span = {}

    def work():
        span["start"] = time.perf_counter()
        d.detect(big)
        span["end"] = time.perf_counter()

    t = threading.Thread(target=work)
    ticks = []
    t.start()
    while t.is_alive():
        ticks.append(time.perf_counter())
    t.join()
    during = [x for x in ticks if span["start"] + 0.05 < x < span["end"] - 0.05]
    assert span["end"] - span["start"] > 0.2, "the detection was too short to tell"
    # With the lock held, the main thread could not run at all inside the call.
    assert len(during) > 1000, f"{len(during)} ticks during a {span['end'] - span['start']:.2f} s call"


def test_a_detector_shared_between_threads(office):
    from concurrent.futures import ThreadPoolExecutor

    d = oc.Detector("ogm-robust", "cpu")
    want = d.detect(office).array
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: (d.detect(office).array, d.detector), range(8)))
    for got, name in results:
        np.testing.assert_array_equal(got, want)
        assert name == "ogm-robust"
