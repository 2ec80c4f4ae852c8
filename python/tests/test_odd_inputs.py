"""Odd inputs and round trips in the package: a non-finite yaw is read as 0 with a warning (as the command
line reads a yaml's `nan`), pickled maps keep where they came from, a many-map merge comes back from a
process pool, a quoted image name keeps its spaces, and a thread count meant for another machine is capped.
Each test fails on the code before its fix."""

from __future__ import annotations

import math
import os
import pickle
import subprocess
import sys
import warnings

import numpy as np
import pytest

import ogm_corners as oc


@pytest.mark.parametrize("yaw", [math.nan, math.inf, -math.inf])
def test_a_non_finite_yaw_warns_and_is_read_as_zero(office, yaw):
    for make in (
        lambda: office.with_georef(0.05, (1.0, 2.0, yaw)),
        lambda: oc.Map(office.pixels, 0.05, (1.0, 2.0, yaw)),
    ):
        with pytest.warns(RuntimeWarning, match="yaw 0"):
            m = make()
        assert m.origin == (1.0, 2.0, 0.0)
        q = m.to_occupancy_grid().orientation
        assert all(math.isfinite(v) for v in q), q
        assert q == (0.0, 0.0, 0.0, 1.0)


def test_a_yaml_with_a_nan_yaw_gives_a_finite_occupancy_grid(tmp_path, office):
    office.with_georef(0.05, (0.0, 0.0, 0.0)).save(tmp_path / "m.yaml")
    text = (tmp_path / "m.yaml").read_text().replace("0.0]", "nan]")
    (tmp_path / "m.yaml").write_text(text)
    m = oc.load_map(tmp_path / "m.yaml")
    assert any("yaw" in w for w in m.warnings), m.warnings
    grid = m.to_occupancy_grid()
    assert all(math.isfinite(v) for v in grid.origin + grid.orientation), grid.origin


def test_a_pickled_map_keeps_its_source_so_a_merge_names_it(tmp_path, office):
    office.with_georef(0.05).save(tmp_path / "robot-a.yaml")
    m = oc.load_map(tmp_path / "robot-a.yaml")
    back = pickle.loads(pickle.dumps(m))
    assert back.source == m.source and back.source.endswith("robot-a.yaml")
    assert back.warnings == m.warnings
    assert np.array_equal(back.pixels, m.pixels)
    assert (back.resolution, back.origin, back.thresholds) == (m.resolution, m.origin, m.thresholds)


def test_a_many_map_merge_pickles_with_its_merged_maps_and_pictures():
    maps = [m for m, _ in oc.synthetic.robot_maps(oc.synthetic.office(), 3, seed=2)]
    many = oc.merge_many(maps)
    back = pickle.loads(pickle.dumps(many))
    assert back.report == many.report
    assert back.poses == many.poses and back.reasons == many.reasons
    assert back.groups == many.groups
    for g in range(many.groups):
        assert np.array_equal(back.merged_map(g).pixels, many.merged_map(g).pixels)
        assert np.array_equal(back.overlay(g), many.overlay(g))
    assert repr(back) == repr(many)


def test_a_many_map_merge_comes_back_from_a_process_pool():
    # A fresh interpreter, so the pool's start method is the platform's own (fork here) without
    # disturbing this one's threads.
    code = (
        "import concurrent.futures as cf, ogm_corners as oc\n"
        "def run(seed):\n"
        "    maps = [m for m, _ in oc.synthetic.robot_maps(oc.synthetic.office(), 2, seed=seed)]\n"
        "    return oc.merge_many(maps)\n"
        "if __name__ == '__main__':\n"
        "    with cf.ProcessPoolExecutor(1) as pool:\n"
        "        r = pool.submit(run, 2).result()\n"
        "    print(len(r.poses), r.groups)\n"
    )
    out = run_python(code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[0] == "2", out.stdout


def test_a_quoted_image_name_keeps_its_leading_space(tmp_path, office):
    office.with_georef(0.05).save(tmp_path / " lead.yaml")
    assert "' lead.pgm'" in (tmp_path / " lead.yaml").read_text()
    m = oc.load_map(tmp_path / " lead.yaml")
    assert np.array_equal(m.pixels, office.pixels)


def run_python(code: str, **env: str) -> subprocess.CompletedProcess:
    e = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path), **env)
    return subprocess.run([sys.executable, "-c", code], env=e, capture_output=True, text=True,
                          timeout=120)


def test_thousands_of_threads_asked_for_are_capped_with_a_warning():
    out = run_python(
        "import warnings\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    import ogm_corners as oc\n"
        "print([str(x.message) for x in w])\n"
        "oc.detect(oc.synthetic.office())\n",
        RAYON_NUM_THREADS="4096",
    )
    assert out.returncode == 0, out.stderr
    assert "RAYON_NUM_THREADS=4096" in out.stdout, out.stdout


def test_probing_for_a_gpu_without_a_desktop_session_prints_no_wayland_error():
    env = {k: v for k, v in os.environ.items() if k not in ("XDG_RUNTIME_DIR", "NODEVICE_SELECT")}
    env["PYTHONPATH"] = os.pathsep.join(sys.path)
    out = subprocess.run(
        [sys.executable, "-c", "import ogm_corners as oc; oc.Detector(backend='auto')"],
        env=env, capture_output=True, text=True, timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert "XDG_RUNTIME_DIR" not in out.stderr, out.stderr


def test_warnings_module_is_quiet_for_a_finite_yaw(office):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        office.with_georef(0.05, (0.0, 0.0, 0.5))
