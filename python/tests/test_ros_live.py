"""The map-merge node's logic without ROS (``ogm_corners.ros.live``): growing maps of simulated robots in,
world poses against the truth and a stable merged grid out."""

import math

import numpy as np
import pytest

from ogm_corners import synthetic
from ogm_corners.ros.live import (
    NOT_ESTIMATED, Candidate, Grid, LiveMerge, Options, check_grid, pose_distance, pose_matrix,
)
from ogm_corners.ros.scenario import crop_known, explored, frame_of_pixels, geodesic, pair_errors


def pixel_pose(theta_deg: float, tx: float, ty: float) -> np.ndarray:
    c, s = math.cos(math.radians(theta_deg)), math.sin(math.radians(theta_deg))
    return np.array([[c, -s, tx], [s, c, ty], [0, 0, 1.0]])


@pytest.fixture(scope="module")
def robots():
    """Three robots' maps of one office, each with its map frame's true pose in robot 0's map frame."""
    office = synthetic.office(1024, 768, seed=3)
    res = office.resolution
    out = []
    for m, (theta, tx, ty) in synthetic.robot_maps(office, 3, seed=2):
        g = m.to_occupancy_grid()
        cells = g.data.reshape(g.height, g.width)
        frame = frame_of_pixels(office.height, res) @ pixel_pose(theta, tx, ty) @ np.linalg.inv(
            frame_of_pixels(m.height, res)
        )
        out.append((cells, res, frame))
    base = np.linalg.inv(out[0][2])
    return [(c, r, base @ f) for c, r, f in out]


def revealed(cells: np.ndarray, share: float) -> np.ndarray:
    """What a robot has seen so far: its known cells within a growing disc about their centre."""
    ys, xs = np.nonzero(cells >= 0)
    cy, cx = ys.mean(), xs.mean()
    radius = share * np.hypot(ys - cy, xs - cx).max()
    yy, xx = np.mgrid[0 : cells.shape[0], 0 : cells.shape[1]]
    out = cells.copy()
    out[np.hypot(yy - cy, xx - cx) > radius] = -1
    return out


def truth_pose(m: np.ndarray):
    return (m[0, 2], m[1, 2], math.atan2(m[1, 0], m[0, 0]))


def test_growing_maps_are_placed_right_and_never_jump(robots):
    live = LiveMerge(Options())
    seen = {}
    origins = []
    for stage, share in enumerate([0.55, 0.8, 1.0]):
        for i, (cells, res, _) in enumerate(robots):
            live.update(f"robot{i + 1}", Grid(revealed(cells, share), res, (0.0, 0.0, 0.0), float(stage)))
        assert live.needs_estimation()
        events = live.estimate()
        assert not live.needs_estimation()
        assert not [e for e in events if e.kind == "moved"], events
        for name, pose in live.poses().items():
            i = int(name[5:]) - 1
            d, deg = pose_distance(pose, truth_pose(robots[i][2]), 50.0)
            assert d < 0.5 and deg < 1.0, (stage, name, pose, truth_pose(robots[i][2]))
            if name in seen:
                # Once placed, a robot's pose only refines.
                assert pose_distance(pose, seen[name], 50.0)[0] < 0.5
            seen[name] = pose
        origins.append(live.merged()[2])
    assert sorted(seen) == ["robot1", "robot2", "robot3"], live.reasons()
    cells, res, origin = live.merged()
    # The merged grid holds every robot's free space: more known cells than any one map.
    assert np.count_nonzero(cells >= 0) > max(np.count_nonzero(c >= 0) for c, _, _ in robots)
    assert res == pytest.approx(robots[0][1])
    # Cells stay put as the maps grow: the origin moves by whole cells.
    for a, b in zip(origins, origins[1:]):
        for k in (0, 1):
            assert (b[k] - a[k]) / res == pytest.approx(round((b[k] - a[k]) / res), abs=1e-6)
    # A merged map past max_cells is refused before it is drawn.
    with pytest.raises(ValueError, match="over max_cells"):
        live.merged(max_cells=1000)


def test_a_pose_moves_only_when_a_change_is_seen_twice_and_never_flips():
    live = LiveMerge(Options(pose_tolerance_m=0.5, pose_tolerance_deg=3.0, confirm=2))
    reach = ((0.0, 0.0), 10.0)  # cells spread 10 m about the frame's origin
    a, b = (1.0, 2.0, 0.1), (4.0, 2.0, 0.1)
    assert [e.kind for e in live._fold("r", a, reach)] == ["placed"]
    assert live._fold("r", (1.1, 2.0, 0.1), reach) == []  # a refinement, smoothed
    assert live._placements["r"].pose[0] == pytest.approx(1.05)
    # Two answers in turn: the pose never leaves the first.
    for _ in range(3):
        assert [e.kind for e in live._fold("r", b, reach)] == ["held"]
        live._fold("r", a, reach)
    assert live._placements["r"].pose[0] < 1.2
    # The same change seen twice in a row is taken, and said.
    live._fold("r", b, reach)
    moved = live._fold("r", b, reach)
    assert [e.kind for e in moved] == ["moved"] and "seen in 2 estimations" in moved[0].text
    assert live._placements["r"].pose == b


@pytest.mark.parametrize("wrong_robot", ["robot1", "robot2"])
def test_known_poses_are_used_and_the_one_the_maps_contradict_is_named(robots, wrong_robot):
    # robot1 is the first to arrive (the anchor of the estimate): a wrong pose there is found too.
    wrong = (5.0, -3.0, 0.5)
    init = {f"robot{i + 1}": truth_pose(robots[i][2]) for i in range(3)}
    init[wrong_robot] = wrong
    live = LiveMerge(Options(init_poses=init))
    for i, (cells, res, _) in enumerate(robots):
        live.update(f"robot{i + 1}", Grid(cells, res, (0.0, 0.0, 0.0), 0.0))
    events = live.estimate()
    assert live.poses()[wrong_robot] == wrong  # given, kept
    said = [e for e in events if e.kind == "contradicts"]
    assert [e.robot for e in said] == [wrong_robot], said
    assert "given pose is kept" in said[0].text
    assert live.reasons()[wrong_robot] == said[0].text  # in the status too
    # Said once: the next estimation finds the same and says nothing new.
    live.update("robot1", Grid(robots[0][0], robots[0][1], (0.0, 0.0, 0.0), 1.0))
    assert not [e for e in live.estimate() if e.kind == "contradicts"]


def test_bad_messages_are_named():
    ok = dict(width=4, height=2, resolution=0.05, origin=(0.0, 0.0, 0.0), max_cells=100)
    assert check_grid(b"\0" * 8, **ok) is None
    assert "7 cells for a 4 x 2 grid" in check_grid(b"\0" * 7, **ok)
    assert "resolution nan" in check_grid(b"\0" * 8, **{**ok, "resolution": float("nan")})
    assert "not finite" in check_grid(b"\0" * 8, **{**ok, "origin": (float("inf"), 0.0, 0.0)})
    assert "over the limit" in check_grid(b"", **{**ok, "width": 10**5, "height": 10**4})
    assert "empty" in check_grid(b"", **{**ok, "width": 0})


def test_real_buildings_grow_live_and_no_robot_is_ever_placed_wrongly(merge_pairs):
    """Five robots on the F5 floor (bent maps, symmetric corridors) and the four of the HIH apartment given to
    one live merge, their maps growing as an exploration along the free space from their middle
(``ogm_corners.ros.scenario``): at every estimation every pair of
    placed robots passes the pair success test of pairs.json (rotation within 5 degrees, RMS over the annotated
    points within the limit), the apartment is never placed with the floor, and the floor's robots are placed
    once their maps suffice."""
    import json

    import ogm_corners as oc

    truth = json.loads((merge_pairs / "pairs.json").read_text())
    pairs = {(p["src"], p["dst"]): p for p in truth["pairs"]}
    res = 0.05
    names = [f"F5_0{k}" for k in range(1, 6)] + [f"HIH_0{k}" for k in range(1, 5)]
    grids = {}
    for n in names:
        m = oc.load_map(merge_pairs / "maps" / f"{n}.png").with_georef(res)
        g = m.to_occupancy_grid()
        cells = g.data.reshape(g.height, g.width)
        grids[n] = (cells, g.height, geodesic(cells))
    live = LiveMerge(Options())
    wrong, near, checked = [], [], 0
    for stage, share in enumerate([0.4, 0.6, 0.8, 1.0]):
        for n in names:
            cells, _, distance = grids[n]
            crop, origin = crop_known(explored(cells, distance, share), res)
            live.update(n, Grid(crop, res, origin, float(stage)))
        live.estimate()
        poses = live.poses()
        for (src, dst), p in pairs.items():
            if src not in poses or dst not in poses:
                continue
            off, rms = pair_errors(poses[src], poses[dst], p, (grids[src][1], grids[dst][1]), res)
            checked += 1
            if off > p["rot_limit_deg"] or rms > 1.25 * p["rms_limit_px"]:
                wrong.append((stage, src, dst, round(off, 2), round(rms, 1), p["rms_limit_px"]))
            elif rms > p["rms_limit_px"]:
                near.append((stage, src, dst, round(off, 2), round(rms, 1), p["rms_limit_px"]))
        floor = [n for n in poses if n.startswith("F5")]
        apartment = [n for n in poses if n.startswith("HIH")]
        assert not (floor and apartment), ("two buildings placed together", stage, poses)
    # Wrong: a turn past the limit or an RMS past 1.25x it (a room or a corridor off). A near miss (the
    # pair's RMS just over its limit on this bent floor, as the library's placement of a subset of it can
    # give: docs/merging.md) is allowed once, and said in docs/ros.md.
    assert not wrong, wrong
    assert len({(a, b) for _, a, b, *_ in near if a < b}) <= 1, near
    assert checked > 0
    # The first robot to arrive (F5_01) anchors the world: the floor's robots are placed in it, the
    # apartment's are not (their own group), and say so.
    placed = live.poses()
    assert len([n for n in placed if n.startswith("F5")]) >= 4, (placed, live.reasons())
    assert not [n for n in placed if n.startswith("HIH")]
    assert all("not with the anchor" in live.reasons()[n] for n in names if n.startswith("HIH")), live.reasons()


def test_map_updates_patch_a_copy_and_bad_windows_are_named():
    live = LiveMerge(Options())
    cells = np.full((4, 5), -1, np.int8)
    assert live.patch("r", 0, 0, 1, 1, b"\0", 0.0) == "an update before any full map"
    live.update("r", Grid(cells, 0.05, (0.0, 0.0, 0.0), 0.0))
    assert live.patch("r", 1, 2, 3, 2, bytes([0, 100, 0, 100, 0, 100]), 1.0) is None
    g = live._grids["r"]
    assert g.cells[2:4, 1:4].tolist() == [[0, 100, 0], [100, 0, 100]] and g.stamp == 1.0 and g.known == 6
    assert (cells == -1).all()  # the first map, which an estimation may be reading, is unchanged
    assert "outside the 5 x 4 map" in live.patch("r", 3, 0, 3, 1, b"\0\0\0", 2.0)
    assert "outside" in live.patch("r", -1, 0, 1, 1, b"\0", 2.0)
    assert "5 cells for a 3 x 2 update" in live.patch("r", 0, 0, 3, 2, b"\0" * 5, 2.0)


def test_a_robot_placed_on_part_of_its_map_waits_for_a_second_estimation_to_agree(robots):
    """The first estimate is not published; the next one on grown maps that agrees is; one that does not
    agree replaces it and waits again. With no growth, the same answer settle_s later is taken."""
    live = LiveMerge(Options(settle_s=3600.0))
    cells, res, _ = robots[0]
    live.update("a", Grid(revealed(cells, 0.5), res, (0.0, 0.0, 0.0), 0.0))
    live.update("b", Grid(revealed(robots[1][0], 0.5), res, (0.0, 0.0, 0.0), 0.0))
    assert live.estimate() == [] and live.poses() == {}
    assert "waiting for a second estimation" in live.reasons()["b"]
    assert not live.needs_estimation()  # nothing grew, and the settling time is far
    # The merged map meanwhile: one robot's map as the world, as before any placement.
    assert live.merged() is not None
    live.update("b", Grid(robots[1][0], res, (0.0, 0.0, 0.0), 1.0))
    placed = live.estimate()
    assert sorted(e.robot for e in placed) == ["a", "b"] and "found again on grown maps" in placed[0].text
    # An estimate that disagrees with a candidate replaces it.
    fresh = LiveMerge(Options(settle_s=0.0))
    fresh._candidates["x"] = Candidate((5.0, 0.0, 0.0), {}, 0.0)
    assert fresh._confirm("x", (0.0, 0.0, 0.0), ((0.0, 0.0), 10.0), {}) == [] and fresh._candidates["x"].pose == (0.0, 0.0, 0.0)
    # Settled: the same answer with no growth, settle_s later, is taken.
    assert [e.kind for e in fresh._confirm("x", (0.0, 0.0, 0.0), ((0.0, 0.0), 10.0), {})] == ["placed"]


def test_the_merged_map_redraws_only_the_robot_that_changed(robots):
    live = LiveMerge(Options(settle_s=0.0))
    for i, (cells, res, _) in enumerate(robots):
        live.update(f"r{i}", Grid(cells, res, (0.0, 0.0, 0.0), 0.0))
    live.estimate()
    live.estimate()  # the second look confirms
    assert len(live.poses()) == 3, live.reasons()
    first = live.merged()
    kept = {r: v[3] for r, v in live._layers.items()}
    cells, res, _ = robots[1]
    grown = cells.copy()
    grown[np.nonzero(grown < 0)[0][0], np.nonzero(grown < 0)[1][0]] = 100
    live.update("r1", Grid(grown, res, (0.0, 0.0, 0.0), 1.0))
    second = live.merged()
    assert live._layers["r0"][3] is kept["r0"] and live._layers["r2"][3] is kept["r2"]
    assert live._layers["r1"][3] is not kept["r1"]
    # The same as drawing everything afresh, and as a plain float64 drawing of every world cell's centre
    # (nearest map cell; occupied over free over unknown) but for a few cells on exact cell boundaries.
    again = LiveMerge(Options())
    again._grids, again._placements = dict(live._grids), dict(live._placements)
    redrawn = again.merged()
    assert np.array_equal(second[0], redrawn[0]) and second[1:] == redrawn[1:]
    assert np.count_nonzero(second[0] == 100) >= np.count_nonzero(first[0] == 100)
    cells, res, (x0, y0, _) = second
    h, w = cells.shape
    wx, wy = np.meshgrid(x0 + (np.arange(w) + 0.5) * res, y0 + (np.arange(h) + 0.5) * res)
    occupied, free = np.zeros((h, w), bool), np.zeros((h, w), bool)
    for r, p in live._placements.items():
        g = live._grids[r]
        m = np.linalg.inv(pose_matrix(p.pose) @ pose_matrix(g.origin))
        gx = np.floor((m[0, 0] * wx + m[0, 1] * wy + m[0, 2]) / g.resolution).astype(np.int64)
        gy = np.floor((m[1, 0] * wx + m[1, 1] * wy + m[1, 2]) / g.resolution).astype(np.int64)
        inside = (gx >= 0) & (gx < g.cells.shape[1]) & (gy >= 0) & (gy < g.cells.shape[0])
        v = np.where(inside, g.cells[np.where(inside, gy, 0), np.where(inside, gx, 0)], -1)
        occupied |= v >= 65
        free |= (v >= 0) & (v <= 25)
    reference = np.where(occupied, 100, np.where(free, 0, -1))
    assert np.count_nonzero(reference != cells) <= 1e-4 * cells.size, np.count_nonzero(reference != cells)
    assert live.last_drawn["r1"] == (1.0, live._placements["r1"].pose)


def test_the_world_is_fixed_only_by_a_published_placement(robots):
    """Robots grouped on a first look but never published do not fix the world: when one of them turns
    out unplaceable (its map replaced by another place's), the others are placed without it."""
    live = LiveMerge(Options(settle_s=0.0))
    res = robots[0][1]
    # "z" arrives first with r0's map (so it is grouped with the others, and their first anchor).
    live.update("z", Grid(robots[0][0].copy(), res, (0.0, 0.0, 0.0), 0.0))
    for i, (cells, _, _) in enumerate(robots):
        live.update(f"r{i}", Grid(cells, res, (0.0, 0.0, 0.0), 0.0))
    live.estimate()  # candidates only
    assert live.poses() == {} and live._anchor is None and "z" in live._candidates
    other = synthetic.office(400, 300, seed=11).to_occupancy_grid()
    live.update("z", Grid(other.data.reshape(other.height, other.width), res, (0.0, 0.0, 0.0), 1.0))
    live.estimate()
    placed = live.poses()
    assert sorted(placed) == ["r0", "r1", "r2"], (placed, live.reasons())
    assert live._anchor == "r0" and placed["r0"] == (0.0, 0.0, 0.0)


def test_a_robot_not_yet_estimated_has_a_reason(robots):
    # Before: reasons() left it out, and the node's status said `reason: null` for it.
    live = LiveMerge(Options())
    (c1, res, _), (c2, _, _) = robots[0], robots[1]
    live.update("robot1", Grid(c1, res, (0.0, 0.0, 0.0), 0.0))
    assert live.reasons() == {"robot1": NOT_ESTIMATED}
    live.estimate()
    first = live.reasons()["robot1"]
    assert first != NOT_ESTIMATED and first
    live.update("robot2", Grid(c2, res, (0.0, 0.0, 0.0), 1.0))
    assert live.reasons() == {"robot1": first, "robot2": NOT_ESTIMATED}
