"""The ROS bag example (examples/merge_rosbag.py) on bags written here with rosbags: ROS 2 in mcap and
sqlite3 storage, and ROS 1, each holding three synthetic robots' maps with known poses, decoys and
messages the topic and type filters must leave out.

rosbags is a test dependency (the ``test`` extra): missing, the test skips with a reason, and fails
under CI=true.
"""

from __future__ import annotations

import importlib.util
import math
import os
import pathlib

import numpy as np
import pytest

import ogm_corners as oc

if os.environ.get("CI") == "true":
    # Under CI a check that did not run is a failure, not a skip.
    try:
        import rosbags  # noqa: F401

        why = None
    except ImportError as e:
        why = str(e)
    if why is not None:
        pytest.fail(f"rosbags is not importable ({why}): required under CI=true", pytrace=False)
else:
    pytest.importorskip(
        "rosbags",
        reason="SKIPPED: rosbags is not installed (pip install rosbags): the ROS bag example did NOT run",
    )

from rosbags.rosbag2 import StoragePlugin, Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

try:
    from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
except ImportError:  # pragma: no cover - every rosbags release so far has it
    Writer1 = None

EXAMPLE = pathlib.Path(__file__).resolve().parent.parent / "examples" / "merge_rosbag.py"
GRID = "nav_msgs/msg/OccupancyGrid"
ROBOT_TOPICS = [f"/robot{i}/map" for i in range(3)]
SEC = 1_000_000_000

KINDS = ["mcap", "sqlite3"] + (["ros1"] if Writer1 is not None else [])


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("merge_rosbag", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def robots():
    """Three robots' maps, each with its exact pose (theta_deg, tx, ty): its pixels to the source's."""
    src = oc.synthetic.office(800, 600, seed=2)
    return oc.synthetic.robot_maps(src, 3, seed=5)


def grid_message(typestore, grid: oc.OccupancyGrid, stamp_ns: int, frame_id: str = "map"):
    """A rosbags OccupancyGrid message holding ``grid``, stamped ``stamp_ns``, its fields filled by hand."""
    t = typestore.types
    time = t["builtin_interfaces/msg/Time"](sec=stamp_ns // SEC, nanosec=stamp_ns % SEC)
    header_type = t["std_msgs/msg/Header"]
    header_fields = {"stamp": time, "frame_id": frame_id}
    if "seq" in header_type.__dataclass_fields__:  # ROS 1
        header_fields["seq"] = 0
    qx, qy, qz, qw = grid.orientation
    origin = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=grid.origin[0], y=grid.origin[1], z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
    )
    info = t["nav_msgs/msg/MapMetaData"](
        map_load_time=time, resolution=grid.resolution, width=grid.width, height=grid.height,
        origin=origin,
    )
    return t[GRID](
        header=header_type(**header_fields), info=info,
        data=np.asarray(grid.data, dtype=np.int8),
    )


def decoy_grid() -> oc.OccupancyGrid:
    """A tiny all-unknown grid, as a map server publishes before the robot has mapped anything."""
    return oc.OccupancyGrid(
        data=np.full(100, -1, dtype=np.int8), width=10, height=10, resolution=0.05,
        origin=(0.0, 0.0, 0.0),
    )


def real_stamp(i: int) -> int:
    return (10 + i) * SEC


def write_bag(directory: pathlib.Path, kind: str, robots) -> pathlib.Path:
    """Writes the test bag; returns its path (a folder for ROS 2, a .bag file for ROS 1).

    On each /robotN/map: a decoy at 1 s and the real map at 10+N s; robot 1's decoy is written after
    its real map, so "latest" must go by the timestamps, not the order. Also a real grid on /other/map
    (outside the pattern) at 20 s and a std_msgs/String on /robot3/map (inside it, the wrong type)."""
    if kind == "ros1":
        typestore = get_typestore(Stores.ROS1_NOETIC)
        path = directory / "run.bag"
        writer = Writer1(path)
        serialize = typestore.serialize_ros1
    else:
        typestore = get_typestore(Stores.ROS2_HUMBLE)
        path = directory / f"run_{kind}"
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=Writer2.VERSION_LATEST, storage_plugin=plugin)
        serialize = typestore.serialize_cdr

    with writer:
        def add(topic: str, msgtype: str):
            return writer.add_connection(topic, msgtype, typestore=typestore)

        def put(connection, stamp_ns: int, msg, msgtype: str = GRID) -> None:
            writer.write(connection, stamp_ns, serialize(msg, msgtype))

        for i, (robot, _) in enumerate(robots):
            c = add(ROBOT_TOPICS[i], GRID)
            decoy = (c, 1 * SEC, grid_message(typestore, decoy_grid(), 1 * SEC))
            real = (c, real_stamp(i), grid_message(typestore, robot.to_occupancy_grid(), real_stamp(i)))
            for args in ((real, decoy) if i == 1 else (decoy, real)):
                put(*args)
        other = add("/other/map", GRID)
        put(other, 20 * SEC, grid_message(typestore, robots[0][0].to_occupancy_grid(), 20 * SEC))
        status = add("/robot3/map", "std_msgs/msg/String")
        put(status, 21 * SEC, typestore.types["std_msgs/msg/String"](data="not a map"),
            "std_msgs/msg/String")
    return path


@pytest.fixture(scope="module", params=KINDS)
def bag(request, tmp_path_factory, robots) -> pathlib.Path:
    return write_bag(tmp_path_factory.mktemp(f"bag_{request.param}"), request.param, robots)


def wrap(deg: float) -> float:
    """An angle in degrees to (-180, 180]."""
    deg = math.fmod(deg, 360.0)
    if deg <= -180.0:
        deg += 360.0
    elif deg > 180.0:
        deg -= 360.0
    return deg


def test_latest_grids_keeps_the_latest_map_of_each_matching_topic(example, bag, robots):
    grids = example.latest_grids(bag, "/robot*/map")
    assert list(grids) == ROBOT_TOPICS  # not /other/map, not the String on /robot3/map
    for i, topic in enumerate(ROBOT_TOPICS):
        msg, robot = grids[topic], robots[i][0]
        stamp = msg.header.stamp
        assert stamp.sec * SEC + stamp.nanosec == real_stamp(i), topic
        assert (msg.info.width, msg.info.height) == (robot.width, robot.height), topic
        assert msg.info.resolution == pytest.approx(robot.resolution)
        m = oc.Map.from_occupancy_grid(msg)
        assert m.origin == pytest.approx(robot.origin)
        assert np.array_equal(m.pixels, robot.pixels), f"{topic}: the cells changed on the way"
    assert list(example.latest_grids(bag, "/other/*")) == ["/other/map"]
    assert example.latest_grids(bag, "/nothing/*") == {}


@pytest.fixture(scope="module")
def mcap_bag(tmp_path_factory, robots) -> pathlib.Path:
    """One bag for the merge itself: merging does not depend on the bag's format (read above)."""
    return write_bag(tmp_path_factory.mktemp("bag_merge"), "mcap", robots)


def test_main_merges_the_robots_to_the_truth(example, mcap_bag, robots, tmp_path, capsys):
    bag = mcap_bag
    out = tmp_path / "merged.yaml"
    png = tmp_path / "overlay.png"
    assert example.main([str(bag), "-o", str(out), "--overlay", str(png)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert (tmp_path / "merged.yaml").is_file() and (tmp_path / "merged.pgm").is_file()
    for topic in ROBOT_TOPICS:
        assert any(line.startswith(f"{topic}  placed  group 0") for line in printed), printed

    # The same merge through the API, on the maps the example read.
    grids = example.latest_grids(bag, "/robot*/map")
    maps = [oc.Map.from_occupancy_grid(msg) for msg in grids.values()]
    merged, poses = oc.merge_many(maps, names=list(grids))
    assert all(p is not None for p in poses), poses
    assert oc.load_map(out).shape == merged.shape

    # Robot 1 relative to robot 0, merged and true (both pixels to pixels, y down).
    (_, t0), (robot1, t1) = robots[0], robots[1]
    turn = wrap(poses[1].theta_deg - poses[0].theta_deg)
    assert abs(wrap(turn - (t1[0] - t0[0]))) < 2.0, (turn, t1[0] - t0[0])
    centre = np.array([robot1.width / 2, robot1.height / 2, 1.0])
    got = np.linalg.inv(poses[0].matrix) @ poses[1].matrix @ centre
    want = np.linalg.inv(oc.rigid_matrix(*t0)) @ oc.rigid_matrix(*t1) @ centre
    assert np.hypot(*(got - want)[:2]) < 5.0, (got, want)

    # The overlay: a PNG the size of the merged map.
    head = png.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    assert (int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")) == (
        merged.width, merged.height,
    )


def test_fewer_than_two_topics_is_an_input_error(example, bag, tmp_path, capsys):
    out = tmp_path / "merged.yaml"
    assert example.main([str(bag), "--topics", "/robot1/map", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "at least two topics" in err, err
    assert not out.exists()


def test_a_missing_bag_is_an_input_error(example, tmp_path, capsys):
    assert example.main([str(tmp_path / "absent.bag")]) == 2
    assert "no such bag" in capsys.readouterr().err


def test_maps_with_nothing_in_common_are_declined(example, tmp_path, capsys):
    """Two blank grids: nothing to place together, exit 3 and nothing written."""
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "blank"
    with Writer2(path, version=Writer2.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic in ROBOT_TOPICS[:2]:
            c = writer.add_connection(topic, GRID, typestore=typestore)
            msg = grid_message(typestore, decoy_grid(), SEC)
            writer.write(c, SEC, typestore.serialize_cdr(msg, GRID))
    out = tmp_path / "merged.yaml"
    assert example.main([str(path), "-o", str(out)]) == 3
    captured = capsys.readouterr()
    assert captured.out.count("not placed") == 2, captured.out
    assert captured.err.startswith("merge_rosbag: declined:") and captured.err.count("\n") == 1
    assert not out.exists()


def test_replay_places_the_robots_as_the_many_map_merge_does(example, mcap_bag, tmp_path, capsys):
    """``python -m ogm_corners.ros.replay``: the bag's maps in time order through the node's logic (the
    decoys first, then the real maps), the final poses as merge_many places the latest maps."""
    from ogm_corners.ros import replay

    out, poses_file = tmp_path / "merged.yaml", tmp_path / "poses.json"
    assert replay.main([str(mcap_bag), "-o", str(out), "--poses", str(poses_file), "--period", "0"]) == 0
    printed = capsys.readouterr().out
    assert "placed at" in printed and (tmp_path / "merged.pgm").is_file(), printed
    doc = __import__("json").loads(poses_file.read_text())
    robots = [t.rsplit("/", 1)[0] for t in ROBOT_TOPICS]
    assert all(doc["robots"][r] is not None for r in robots), doc
    grids = example.latest_grids(mcap_bag, "/robot*/map")
    many = oc.merge_many([oc.Map.from_occupancy_grid(m) for m in grids.values()], names=list(grids))
    w = {t.rsplit("/", 1)[0]: p.world.matrix for t, p in zip(grids, many.poses)}
    from ogm_corners.ros.live import matrix_pose, pose_distance, pose_matrix

    def pose(r):
        p = doc["robots"][r]
        return pose_matrix((p["x"], p["y"], p["yaw"]))

    for r in robots[1:]:
        got = matrix_pose(np.linalg.inv(pose(robots[0])) @ pose(r))
        want = matrix_pose(np.linalg.inv(w[robots[0]]) @ w[r])
        d, deg = pose_distance(got, want, 0.0)
        assert d < 0.2 and deg < 0.5, (r, got, want)
    assert oc.load_map(out).width > max(m.info.width for m in grids.values())
    # Bad input: one line, exit 2.
    assert replay.main([str(tmp_path / "nothing.bag")]) == 2
    assert "no such bag" in capsys.readouterr().err
