"""Maps: ROS OccupancyGrid round trips, messages as rclpy delivers them, files."""

from __future__ import annotations

import array
import math
from types import SimpleNamespace

import numpy as np
import pytest

import ogm_corners as oc


def grid_msg(data, width, height, resolution=0.05, x=1.5, y=-2.0, yaw=0.3):
    """An object shaped like nav_msgs/OccupancyGrid as rclpy delivers it (data: array('b'))."""
    q = SimpleNamespace(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
    pose = SimpleNamespace(position=SimpleNamespace(x=x, y=y, z=0.0), orientation=q)
    info = SimpleNamespace(width=width, height=height, resolution=resolution, origin=pose)
    return SimpleNamespace(info=info, data=data)


def test_occupancy_grid_round_trip_flips_rows():
    # 3 wide, 2 high, row 0 at the bottom: [-1, 0, 100] is the bottom row.
    cells = [-1, 0, 100, 100, 0, -1]
    m = oc.Map.from_occupancy_grid(cells, 3, 2, 0.05, (1.0, 2.0, 0.0))
    assert m.shape == (2, 3)
    np.testing.assert_array_equal(m.pixels, [[0, 254, 205], [205, 254, 0]])
    g = m.to_occupancy_grid()
    assert g.data.dtype == np.int8 and g.data.tolist() == cells
    assert (g.width, g.height, g.resolution, g.origin) == (3, 2, 0.05, (1.0, 2.0, 0.0))


def test_every_container_rclpy_and_rosbags_use(office):
    g = office.to_occupancy_grid()
    want = office.pixels
    for data in (g.data, g.data.tolist(), array.array("b", g.data.tobytes()), g.data.tobytes(),
                 g.data.reshape(g.height, g.width)):
        m = oc.Map.from_occupancy_grid(data, g.width, g.height, g.resolution, g.origin)
        np.testing.assert_array_equal(m.pixels, want)


def test_a_message_passes_straight_in_and_fill_writes_one_back(office):
    g = office.to_occupancy_grid()
    msg = grid_msg(array.array("b", g.data.tobytes()), g.width, g.height, yaw=0.3)
    m = oc.Map.from_occupancy_grid(msg)
    assert m.origin == pytest.approx((1.5, -2.0, 0.3))
    np.testing.assert_array_equal(m.pixels, office.pixels)
    out = grid_msg(array.array("b"), 0, 0)
    m.to_occupancy_grid().fill(out)
    assert isinstance(out.data, array.array) and out.data.tobytes() == g.data.tobytes()
    assert (out.info.width, out.info.height) == (g.width, g.height)
    q = out.info.origin.orientation
    assert 2 * math.atan2(q.z, q.w) == pytest.approx(0.3)
    # World coordinates of a keypoint agree with ROS's cell-centre convention.
    kp = oc.detect(m, backend="cpu")
    wx, wy = kp.world[0]
    col, row_from_bottom = int(kp.x[0]), m.height - 1 - int(kp.y[0])
    lx, ly = (col + 0.5) * 0.05, (row_from_bottom + 0.5) * 0.05
    assert (wx, wy) == pytest.approx((1.5 + math.cos(0.3) * lx - math.sin(0.3) * ly,
                                      -2.0 + math.sin(0.3) * lx + math.cos(0.3) * ly))


def test_intermediate_values_follow_map_saver_thresholds():
    cells = np.array([0, 25, 26, 64, 65, 100, -1, -7], np.int8)
    m = oc.Map.from_occupancy_grid(cells, 8, 1, 0.1, (0, 0, 0))
    np.testing.assert_array_equal(m.pixels[0], [254, 254, 205, 205, 0, 0, 205, 205])
    m2 = oc.Map.from_occupancy_grid(cells, 8, 1, 0.1, (0, 0, 0), free_thresh=0.1, occupied_thresh=0.9)
    np.testing.assert_array_equal(m2.pixels[0], [254, 205, 205, 205, 205, 0, 205, 205])


@pytest.mark.parametrize(
    "args,message",
    [
        (([0] * 5, 3, 2, 0.05, (0, 0, 0)), "has 6 cells, got 5"),
        (([0] * 6, 3, 2, -1.0, (0, 0, 0)), "resolution"),
        (([0] * 6, 3, 2, 0.05, (math.inf, 0, 0)), "origin"),
        (([300] * 6, 3, 2, 0.05, (0, 0, 0)), "int8"),
        ((["a"] * 6, 3, 2, 0.05, (0, 0, 0)), "int8"),
        (([0] * 6, 3, 2, 0.05, (0, 0)), None),
    ],
)
def test_bad_grids(args, message):
    if message is None:  # a 2-value origin is (x, y) with yaw 0
        assert oc.Map.from_occupancy_grid(*args).origin == (0.0, 0.0, 0.0)
        return
    with pytest.raises(ValueError) as e:
        oc.Map.from_occupancy_grid(*args)
    assert message in str(e.value)


def test_save_and_load(tmp_path, office):
    office.save(tmp_path / "m.yaml")
    back = oc.load_map(tmp_path / "m.yaml")
    np.testing.assert_array_equal(back.pixels, office.pixels)
    assert back.resolution == office.resolution and back.origin == office.origin
    assert back.source.endswith("m.yaml")
    with pytest.raises(ValueError, match="NAME.yaml"):
        office.save(tmp_path / "m.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pgm", "m.yaml"]
    # Its own thresholds go into the yaml, so it reads back the same.
    odd = oc.Map(office.pixels, 0.05, (1.0, 2.0, 0.0), negate=True, occupied_thresh=0.7, free_thresh=0.1)
    odd.save(tmp_path / "odd.yaml")
    again = oc.load_map(tmp_path / "odd.yaml")
    assert again.thresholds == (True, 0.7, 0.1)
    np.testing.assert_array_equal(again.states(), odd.states())


def test_with_georef_shares_pixels(office):
    m = office.with_georef(0.1, (1.0, 2.0, 0.5))
    assert m.resolution == 0.1 and m.origin == (1.0, 2.0, 0.5)
    assert np.shares_memory(m.pixels, office.pixels)


def test_maps_and_keypoints_pickle(office):
    import pickle

    m = pickle.loads(pickle.dumps(office))
    np.testing.assert_array_equal(m.pixels, office.pixels)
    assert (m.resolution, m.origin, m.thresholds) == (office.resolution, office.origin, office.thresholds)
    kp = oc.detect(office, backend="cpu")
    back = pickle.loads(pickle.dumps(kp))
    np.testing.assert_array_equal(back.array, kp.array)
    assert back.detector == kp.detector
