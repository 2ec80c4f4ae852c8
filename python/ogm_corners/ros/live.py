"""The map-merge node's logic without ROS: robots' growing maps in, stable world poses and a merged grid
out. The node (``ogm_corners.ros.node``) feeds it messages; tests and the replay feed it directly.

Frames: each robot's map frame (where its ``OccupancyGrid.info.origin`` lives) is placed in the world
frame by a pose (x, y, yaw: ``w = R(yaw) m + (x, y)``, metres). With no known initial poses the first
robot placed is the anchor: its map frame is the world frame. Poses are of map frames, not of grids, so a
map that grows and moves its origin (slam_toolbox, gmapping) keeps its placement.
"""

from __future__ import annotations

import functools
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .._map import Map
from .._merge import MergeCache, merge_many

#: (x, y, yaw): a map frame's pose in the world frame, metres and radians.
Pose2 = Tuple[float, float, float]


def pose_matrix(p: Pose2) -> np.ndarray:
    c, s = math.cos(p[2]), math.sin(p[2])
    return np.array([[c, -s, p[0]], [s, c, p[1]], [0.0, 0.0, 1.0]])


def matrix_pose(m: np.ndarray) -> Pose2:
    return (float(m[0, 2]), float(m[1, 2]), math.atan2(m[1, 0], m[0, 0]))


def yaw_of(q) -> float:
    """The yaw of a quaternion (x, y, z, w attributes), normalised or not; NaN when it is not finite."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), q.w * q.w + q.x * q.x - q.y * q.y - q.z * q.z)


def pose_distance(a: Pose2, b: Pose2, reach: float) -> Tuple[float, float]:
    """How far two placements of one map are apart: (metres, degrees), the metres the largest displacement
    of a point within ``reach`` metres of the map frame's origin (a turn moves far cells most)."""
    turn = math.remainder(a[2] - b[2], math.tau)
    shift = math.hypot(a[0] - b[0], a[1] - b[1]) + abs(turn) * reach
    return shift, abs(math.degrees(turn))


#: Where a map's known cells are, in its map frame: (their centroid, the RMS of their distances to it), metres.
Spread = Tuple[Tuple[float, float], float]


def cells_moved(a: Pose2, b: Pose2, spread: Spread) -> Tuple[float, float]:
    """How far a map's known cells move between two placements of its frame: (the RMS of their moves,
    metres; the turn, degrees). The RMS is the success test's measure of merged maps (an RMS over points
    spread over the map), here over every known cell: the centroid's move and the turn times the cells'
    spread about it (exact: for a turn d, |R(d) q - q| = 2 sin(d/2) |q|)."""
    (cx, cy), radius = spread
    moved = (pose_matrix(a) - pose_matrix(b)) @ (cx, cy, 1.0)
    turn = math.remainder(a[2] - b[2], math.tau)
    return math.hypot(moved[0], moved[1], 2.0 * math.sin(turn / 2.0) * radius), abs(math.degrees(turn))


#: The reason of a robot whose map has not been through an estimation yet.
NOT_ESTIMATED = "not yet estimated: waiting for the next estimation with its map"

@dataclass
class Grid:
    """One robot's latest map as it arrived: int8 cells, row 0 at the bottom (ROS)."""

    cells: np.ndarray  # (height, width) int8
    resolution: float
    origin: Pose2
    stamp: float
    known: int = 0

    def __post_init__(self) -> None:
        self.known = int(np.count_nonzero(self.cells >= 0))

    @functools.cached_property
    def spread(self) -> Spread:
        """Its known cells' centroid and RMS distance to it, in the map frame (``Spread``)."""
        rows, cols = np.nonzero(self.cells >= 0)
        h, w = self.cells.shape
        if rows.size == 0:
            rows, cols = np.array([h / 2.0]), np.array([w / 2.0])
        r = self.resolution
        centre = pose_matrix(self.origin) @ ((cols.mean() + 0.5) * r, (rows.mean() + 0.5) * r, 1.0)
        return (float(centre[0]), float(centre[1])), float(r * math.sqrt(cols.var() + rows.var()))


def check_grid(
    data: Sequence[int] | np.ndarray | bytes,
    width: int,
    height: int,
    resolution: float,
    origin: Pose2,
    max_cells: int,
) -> Optional[str]:
    """Why a map message cannot be used (one line), or None."""
    if width <= 0 or height <= 0:
        return f"an empty grid ({width} x {height})"
    if width * height > max_cells:
        return f"a grid of {width} x {height} cells, over the limit of {max_cells} (max_cells)"
    if len(data) != width * height:
        return f"{len(data)} cells for a {width} x {height} grid"
    if not (math.isfinite(resolution) and 1e-4 <= resolution <= 1e3):
        return f"resolution {resolution} is not a number of metres between 0.0001 and 1000"
    if not all(math.isfinite(v) for v in origin):
        return f"origin {origin} is not finite"
    if max(abs(origin[0]), abs(origin[1])) > 1e8:
        return f"origin {origin} is over 100000 km from the map frame's origin"
    return None


def grid_of(msg, max_cells: int, stamp: float) -> Tuple[Optional[Grid], Optional[str]]:
    """A ``nav_msgs/OccupancyGrid`` message (rclpy's or rosbags') as a ``Grid``, or why it cannot be used
    (``check_grid``). ``stamp``: when it came, seconds."""
    info, o = msg.info, msg.info.origin
    origin = (o.position.x, o.position.y, yaw_of(o.orientation))
    why = check_grid(msg.data, info.width, info.height, info.resolution, origin, max_cells)
    if why is not None:
        return None, why
    return Grid(cells_of(msg.data, info.width, info.height), float(info.resolution), origin, stamp), None


def cells_of(data: Sequence[int] | np.ndarray | bytes, width: int, height: int) -> np.ndarray:
    """The cells as an (height, width) int8 array: ``array('b')`` and bytes read without a copy."""
    if isinstance(data, np.ndarray):
        a = data.astype(np.int8, copy=False)
    else:
        try:
            a = np.frombuffer(data, dtype=np.int8)  # array('b'), bytes
        except TypeError:
            a = np.asarray(data, dtype=np.int8)
    return a.reshape(height, width)


@dataclass
class Placement:
    """A robot's accepted pose and the pending change that would replace it."""

    pose: Pose2
    pending: Optional[Pose2] = None
    seen: int = 0  # estimates agreeing with ``pending`` in a row


@dataclass
class Candidate:
    """A robot's first placement, not yet published: it waits for a second estimation to agree."""

    pose: Pose2
    evidence: Dict[str, int]  # the version of each map of its group it was found on
    since: float  # the clock when found


@dataclass
class Options:
    """What the node's parameters set (the names are the node's)."""

    #: Re-estimate once a map's known cells have grown by this share since its last estimation.
    growth: float = 0.1
    #: A new estimate within this of the accepted pose refines it (smoothed); beyond, it must be seen
    #: ``confirm`` estimations in a row, agreeing with itself, before the pose moves. The metres are the
    #: RMS move of the map's known cells (``cells_moved``, the success test's measure); 1 m is the success
    #: limit of merged real maps (20 cells at 0.05 m).
    pose_tolerance_m: float = 1.0
    pose_tolerance_deg: float = 3.0
    #: A robot's first placement is published once a second estimation agrees with it: one on grown
    #: maps, or, when no map grows by ``growth``, one this many seconds later (its map has settled).
    settle_s: float = 10.0
    confirm: int = 2
    #: A known initial pose further than this from where the maps place the robot is reported.
    contradiction_m: float = 1.0
    contradiction_deg: float = 5.0
    #: Share of a refinement taken at each estimate (exponential smoothing).
    smoothing: float = 0.5
    backend: str = "cpu"
    #: Known initial poses (robot -> (x, y, yaw)) or None to estimate them.
    init_poses: Optional[Dict[str, Pose2]] = None


@dataclass
class Event:
    """Something a user should know about, once: a robot placed, moved, contradicted, declined."""

    robot: str
    kind: str  # placed | refined | moved | held | contradicts | not_placed
    text: str


class LiveMerge:
    """Robots' maps in, world poses and the merged grid out. Thread-safe: ``update`` from message
    callbacks, ``estimate`` from a worker, ``merged``/``poses`` from a timer."""

    def __init__(self, options: Optional[Options] = None, clock: Callable[[], float] = time.monotonic) -> None:
        """``clock``: seconds, for ``settle_s`` (a replay gives the bag's time)."""
        self.options = options if options is not None else Options()
        self._clock = clock
        self._lock = threading.Lock()
        self._grids: Dict[str, Grid] = {}
        # The version of each map the estimation uses: replaced by the latest when its known area has
        # changed by ``growth`` (so between, its preparation and its pairs come from the cache).
        self._used: Dict[str, Tuple[Grid, Map]] = {}
        self._cache = MergeCache()
        self._last: Dict[str, float] = {}
        self._draw_lock = threading.Lock()
        #: What the last merged map was drawn from: robot -> (its map's stamp, its pose or None).
        self.last_drawn: Dict[str, Tuple[float, Optional[Pose2]]] = {}
        # Each placed robot's drawing in world cells, kept while its map and pose stay the same.
        self._layers: Dict[str, tuple] = {}
        self._placements: Dict[str, Placement] = {}
        self._candidates: Dict[str, Candidate] = {}
        self._versions: Dict[str, int] = {}  # of each robot's map in ``_used``
        self._anchor: Optional[str] = None
        self._reasons: Dict[str, str] = {}
        self._warnings: Dict[str, str] = {}  # about placed robots: a given pose the maps contradict
        self._arrival: Dict[str, int] = {}
        self._version = 0  # bumped when a grid or a pose changes: the merged grid is redrawn then

    # ---- input ----

    def update(self, robot: str, grid: Grid) -> None:
        with self._lock:
            self._arrival.setdefault(robot, len(self._arrival))
            self._grids[robot] = grid
            self._version += 1

    def patch(self, robot: str, x: int, y: int, width: int, height: int,
              data: Sequence[int] | np.ndarray | bytes, stamp: float) -> Optional[str]:
        """A ``map_msgs/OccupancyGridUpdate`` (the cells of a ``width`` x ``height`` window at column ``x``,
        row ``y``) applied to the robot's latest full map, as multirobot_map_merge applies them; or why it
        cannot be (one line). The map is copied, not changed in place: an estimation may be reading it."""
        with self._lock:
            g = self._grids.get(robot)
        if g is None:
            return "an update before any full map"
        h, w = g.cells.shape
        if min(x, y) < 0 or width <= 0 or height <= 0 or x + width > w or y + height > h:
            return f"an update window {width} x {height} at ({x}, {y}) outside the {w} x {h} map"
        if len(data) != width * height:
            return f"{len(data)} cells for a {width} x {height} update"
        cells = g.cells.copy()
        cells[y : y + height, x : x + width] = cells_of(data, width, height)
        self.update(robot, Grid(cells, g.resolution, g.origin, stamp))
        return None

    def robots(self) -> List[str]:
        with self._lock:
            return sorted(self._grids)

    def needs_estimation(self) -> bool:
        """A robot's map is new, or its known cells have changed by ``growth`` since the version the
        estimation uses."""
        with self._lock:
            settled = self._clock() - self.options.settle_s
            return any(self._stale(r) for r in self._grids) or any(
                c.since <= settled for c in self._candidates.values()
            )

    def _stale(self, r: str) -> bool:
        used = self._used.get(r)
        if used is None:
            return True
        g, before = self._grids[r], used[0]
        # Grown by the share, or shrunk by it (a SLAM reset), or at another resolution.
        return abs(g.known - before.known) >= before.known * self.options.growth + 1 or (
            g.resolution != before.resolution
        )

    def last_estimation(self) -> Dict[str, float]:
        """The last estimation: its seconds and how much came from the cache (``MergeCache.last_use``)."""
        with self._lock:
            return dict(self._last)

    # ---- estimation ----

    def estimate(self) -> List[Event]:
        """Places the current maps (the library's many-map placement, or the known poses) and folds the
        result into the accepted poses. Runs the heavy work without the lock."""
        with self._lock:
            stale = {r: self._grids[r] for r in self._grids if self._stale(r)}
            kept = {r: self._used[r] for r in self._grids if r not in stale}
        if not stale and not kept:
            return []
        # Outside the lock: a Map of each new version (the estimation's input from now on).
        for r, g in stale.items():
            kept[r] = (g, Map.from_occupancy_grid(g.cells.reshape(-1), g.cells.shape[1], g.cells.shape[0],
                                                  g.resolution, g.origin))
        snapshot = {r: used[0] for r, used in kept.items()}
        names = sorted(snapshot)
        started = time.monotonic()
        estimates, reasons, anchor = self._place(names, {r: used[1] for r, used in kept.items()})
        with self._lock:
            # Taken as used only once placed: a placement that failed (memory, Ctrl-C) is tried again.
            self._used.update((r, kept[r]) for r in stale)
            for r in stale:
                self._versions[r] = self._versions.get(r, 0) + 1
        last = {"seconds": round(time.monotonic() - started, 4), "robots": len(names),
                **(self._cache.last_use if len(names) > 1 else {})}
        # Outside the lock (a pass over each placed map's cells): how far its cells spread.
        spreads = {r: snapshot[r].spread for r in estimates}
        events: List[Event] = []
        init = self.options.init_poses
        with self._lock:
            if init is not None:
                events += self._check_given(names, estimates)
            for r in names:
                if init is not None:
                    if r not in init:
                        self._reasons[r] = "no initial pose given (map_merge/init_pose_*)"
                        continue
                    if r not in self._placements:
                        self._placements[r] = Placement(init[r])
                        events.append(Event(r, "placed", f"{r}: placed at its given pose {fmt(init[r])}"))
                    continue
                est = estimates.get(r)
                if est is None:
                    why = reasons.get(r) or "not placed"
                    self._candidates.pop(r, None)  # a placement the estimation no longer finds
                    if r not in self._placements and self._reasons.get(r) != why:
                        events.append(Event(r, "not_placed", f"{r}: not placed: {why}"))
                    self._reasons[r] = why
                    continue
                self._reasons.pop(r, None)
                if r in self._placements:
                    events += self._fold(r, est, spreads[r])
                else:
                    events += self._confirm(r, est, spreads[r], {o: self._versions[o] for o in estimates})
            if init is None and self._anchor is None and self._placements:
                # The first placements published: this estimation's anchor is the world from now on.
                self._anchor = anchor
            self._version += 1
            self._last = last
        return events

    def _check_given(self, names: List[str], est: Dict[str, Pose2]) -> List[Event]:
        """Given poses against the maps, pair by pair: where two robots' given poses put them relative to
        each other, against where their maps do. A robot that disagrees with more than half of the others
        is named; with two robots only the pair can be named. Said once per finding."""
        init = self.options.init_poses or {}
        both = [r for r in names if r in init and r in est]
        against: Dict[str, List[str]] = {r: [] for r in both}
        for i, a in enumerate(both):
            for b in both[i + 1 :]:
                given = np.linalg.inv(pose_matrix(init[a])) @ pose_matrix(init[b])
                seen = np.linalg.inv(pose_matrix(est[a])) @ pose_matrix(est[b])
                # The frames' offset and turn, not a far cell's displacement: a given pose is wrong by
                # metres or by many degrees, and the merger's own error (a fraction of a degree) must not
                # read as a contradiction across a large map.
                d, deg = pose_distance(matrix_pose(seen), matrix_pose(given), 0.0)
                if d > self.options.contradiction_m or deg > self.options.contradiction_deg:
                    against[a].append(b)
                    against[b].append(a)
        events = []
        for r in both:
            others = len(both) - 1
            if others >= 2 and len(against[r]) * 2 > others:
                text = (f"{r}: the maps contradict its given pose {fmt(init[r])} (they disagree with it for "
                        f"{len(against[r])} of the {others} other robots); the given pose is kept")
            elif others == 1 and against[r] and r == both[0]:
                text = (f"{r} and {against[r][0]}: their given poses and their maps disagree; which one is "
                        "wrong cannot be told from two robots; the given poses are kept")
            else:
                self._warnings.pop(r, None)
                continue
            if self._warnings.get(r) != text:
                events.append(Event(r, "contradicts", text))
            self._warnings[r] = text
        return events

    def _place(self, names: List[str], maps: Dict[str, Map]
               ) -> Tuple[Dict[str, Pose2], Dict[str, str], Optional[str]]:
        """Each robot's map frame in the anchor's map frame, from one many-map placement (what did not
        change since the last one comes from the cache), why the others are not placed, and the anchor.
        The anchor is the world's once a robot is published; before, it is chosen afresh each time."""
        if len(names) < 2:
            return {}, {n: "waiting for another robot's map" for n in names}, None
        many = merge_many([maps[n] for n in names], names=names, backend=self.options.backend,
                          cache=self._cache)
        frames: Dict[str, np.ndarray] = {}
        group: Dict[str, int] = {}
        reasons: Dict[str, str] = {}
        for n, p, why in zip(names, many.poses, many.reasons):
            if p is None or p.world is None:
                reasons[n] = why or "not placed"
                continue
            frames[n] = p.world.matrix  # the map frame in the group's merged-map frame
            group[n] = p.group
        with self._lock:
            anchor = self._anchor
            if anchor is None or anchor not in frames:
                # The anchor stays the first robot placed; before that, the first of the largest group.
                placed = [n for n in names if n in frames and n in self._placements]
                if anchor is not None and anchor not in frames:
                    reasons_anchor = f"the world's anchor {anchor} is not placed in this estimation"
                    return {}, {n: reasons.get(n, reasons_anchor) for n in names}, None
                first = sorted(frames, key=lambda n: self._arrival.get(n, 1 << 30))
                if placed:
                    anchor = placed[0]
                elif first:
                    # The first to arrive of the largest group (the robot shown alone so far, when it is
                    # in that group: then the world does not move).
                    sizes: Dict[int, int] = {}
                    for n in frames:
                        sizes[group[n]] = sizes.get(group[n], 0) + 1
                    best = max(sizes.values())
                    anchor = next(n for n in first if sizes[group[n]] == best)
                else:
                    return {}, reasons, None
        base = np.linalg.inv(frames[anchor])
        out: Dict[str, Pose2] = {}
        for n, f in frames.items():
            if group[n] != group[anchor]:
                reasons[n] = f"placed with other maps, not with the anchor {anchor}'s"
                continue
            out[n] = matrix_pose(base @ f)
        return out, reasons, anchor

    def _confirm(self, r: str, est: Pose2, spread: Spread, evidence: Dict[str, int]) -> List[Event]:
        """A first placement is published when a second estimation agrees with it: one in which a map of
        its group has changed (new evidence: ``evidence`` gives the versions of the group's maps), or one
        ``settle_s`` after it (none of them grew meanwhile: the same maps, the same answer). A placement on
        a part of a map that the next part contradicts is never shown."""
        o, now = self.options, self._clock()
        c = self._candidates.get(r)
        if c is not None:
            d, deg = cells_moved(est, c.pose, spread)
            if d <= o.pose_tolerance_m and deg <= o.pose_tolerance_deg:
                grown = any(evidence.get(o) != v for o, v in c.evidence.items())
                if grown or now - c.since >= o.settle_s:
                    del self._candidates[r]
                    self._reasons.pop(r, None)
                    self._placements[r] = Placement(est)
                    how = "on grown maps" if grown else f"{now - c.since:.0f} s later"
                    return [Event(r, "placed", f"{r}: placed at {fmt(est)} (found again {how})")]
                self._reasons[r] = f"placed at {fmt(est)}, waiting for a second estimation to agree"
                return []
        self._candidates[r] = Candidate(est, evidence, now)
        self._reasons[r] = f"placed at {fmt(est)}, waiting for a second estimation to agree"
        return []

    def _fold(self, r: str, est: Pose2, spread: Spread) -> List[Event]:
        o = self.options
        p = self._placements.get(r)
        if p is None:
            self._placements[r] = Placement(est)
            return [Event(r, "placed", f"{r}: placed at {fmt(est)}")]
        d, deg = cells_moved(est, p.pose, spread)
        if d <= o.pose_tolerance_m and deg <= o.pose_tolerance_deg:
            p.pose = blend(p.pose, est, o.smoothing)
            p.pending, p.seen = None, 0
            return []
        if p.pending is not None:
            dp, degp = cells_moved(est, p.pending, spread)
            if dp <= o.pose_tolerance_m and degp <= o.pose_tolerance_deg:
                p.seen += 1
            else:
                p.pending, p.seen = est, 1
        else:
            p.pending, p.seen = est, 1
        if p.seen >= o.confirm:
            old = p.pose
            p.pose, p.pending, p.seen = est, None, 0
            return [Event(r, "moved", f"{r}: moved from {fmt(old)} to {fmt(est)} ({d:.2f} m, {deg:.1f} deg), "
                                      f"seen in {o.confirm} estimations in a row")]
        return [Event(r, "held", f"{r}: an estimate {d:.2f} m, {deg:.1f} deg from its pose is held until "
                                 f"it is seen again")]

    # ---- output ----

    def poses(self) -> Dict[str, Pose2]:
        with self._lock:
            return {r: p.pose for r, p in self._placements.items() if r in self._grids}

    def reasons(self) -> Dict[str, str]:
        """Why each robot not placed is not (the latest reason; ``NOT_ESTIMATED`` before its first
        estimation), and what is wrong with a placed one (a given pose the maps contradict)."""
        with self._lock:
            # A robot whose map came after the last estimation has no verdict yet: said so, not left blank.
            out = {r: NOT_ESTIMATED for r in self._grids if r not in self._placements}
            out.update({r: why for r, why in self._reasons.items() if r not in self._placements})
            out.update(self._warnings)
            return out

    @property
    def version(self) -> int:
        with self._lock:
            return self._version

    def merged(
        self, max_cells: int = 1 << 27, resolution: Optional[float] = None
    ) -> Optional[Tuple[np.ndarray, float, Pose2]]:
        """The placed maps drawn into one world-aligned grid: (cells int8 row 0 at the bottom, resolution,
        origin (x, y, 0)); occupied wins over free, free over unknown. None until a robot is placed.
        Raises ValueError, before allocating anything, when the grid would be over ``max_cells``.

        Each robot's map is drawn into world cells once per (map version, pose) and kept: a merged map
        after one robot's update redraws that robot only, and stacks the others' kept layers.
        ``last_drawn`` then says what was drawn: each robot's map stamp and pose (None for the one map
        shown as the world before any placement)."""
        with self._lock:
            placed = [(r, self._grids[r], p.pose) for r, p in self._placements.items() if r in self._grids]
            shown_alone = False
            if not placed and self.options.init_poses is None and self._grids:
                # Until a robot is placed with another, one map is the world: the anchor's once chosen,
                # else the first to arrive (as multirobot_map_merge shows one robot's map).
                only = self._anchor if self._anchor in self._grids else min(
                    self._grids, key=lambda n: self._arrival.get(n, 0))
                placed = [(only, self._grids[only], (0.0, 0.0, 0.0))]
                shown_alone = True
        if not placed:
            return None
        with self._draw_lock:  # the kept layers are one drawer's at a time
            drawn = self._draw(placed, max_cells, resolution)
            self.last_drawn = {r: (g.stamp, None if shown_alone else pose) for r, g, pose in placed}
            return drawn

    def _draw(self, placed: List[Tuple[str, Grid, Pose2]], max_cells: int,
              resolution: Optional[float]) -> Tuple[np.ndarray, float, Pose2]:
        res = resolution or min(g.resolution for _, g, _ in placed)
        # World cells are [i res, (i + 1) res): snapped to the resolution, cells stay put between updates.
        boxes = [world_box(g, pose, res) for _, g, pose in placed]
        x0, y0 = min(b[0] for b in boxes), min(b[1] for b in boxes)
        width, height = max(b[2] for b in boxes) - x0, max(b[3] for b in boxes) - y0
        if width * height > max_cells:
            raise ValueError(
                f"the merged map would be {width} x {height} cells, over max_cells ({max_cells}): are the "
                "robots' origins or given poses far apart?"
            )
        layers = []
        for (r, g, pose), box in zip(placed, boxes):
            key = (id(g), pose, res)
            kept = self._layers.get(r)
            if kept is None or kept[0] != key:
                kept = (key, g, box, draw_layer(g, pose, res, box))
                self._layers[r] = kept  # ``g`` is held with it: its id cannot be reused meanwhile
            layers.append(kept[2:])
        for r in set(self._layers) - {r for r, _, _ in placed}:
            self._layers.pop(r, None)
        cells = np.full((height, width), -1, np.int8)
        for (bx0, by0, bx1, by1), (occupied, free) in layers:
            cells[by0 - y0 : by1 - y0, bx0 - x0 : bx1 - x0][free] = 0
        for (bx0, by0, bx1, by1), (occupied, free) in layers:
            cells[by0 - y0 : by1 - y0, bx0 - x0 : bx1 - x0][occupied] = 100
        return cells, res, (x0 * res, y0 * res, 0.0)


def world_box(g: Grid, pose: Pose2, res: float) -> Tuple[int, int, int, int]:
    """The world cells (first column, first row, past the last column, past the last row) that grid ``g``
    placed by ``pose`` covers."""
    h, w = g.cells.shape
    m = pose_matrix(pose) @ pose_matrix(g.origin)
    c = np.array([(m @ (x * g.resolution, y * g.resolution, 1.0))[:2] for x, y in ((0, 0), (w, 0), (0, h), (w, h))])
    return (math.floor(c[:, 0].min() / res), math.floor(c[:, 1].min() / res),
            math.ceil(c[:, 0].max() / res), math.ceil(c[:, 1].max() / res))


def draw_layer(g: Grid, pose: Pose2, res: float, box: Tuple[int, int, int, int]) -> Tuple[np.ndarray, np.ndarray]:
    """Grid ``g`` placed by ``pose`` sampled at the centres of the world cells of ``box`` (nearest cell):
    (occupied, free) masks of the box's shape."""
    bx0, by0, bx1, by1 = box
    width, height = bx1 - bx0, by1 - by0
    m = np.linalg.inv(pose_matrix(pose) @ pose_matrix(g.origin)) / g.resolution
    occupied = np.zeros((height, width), bool)
    free = np.zeros((height, width), bool)
    h, w = g.cells.shape
    # float32 and about a million cells at a time: fast, and memory stays small. Coordinates are taken
    # from the box's corner (its offset added in float64) so that far origins keep their precision.
    m[:, 2] = m @ (bx0 * res, by0 * res, 1.0)
    f = m.astype(np.float32)
    wx = ((np.arange(width) + 0.5) * res).astype(np.float32)
    band = max(1, (1 << 20) // max(width, 1))
    for top in range(0, height, band):
        rows = min(band, height - top)
        wy = ((np.arange(top, top + rows) + 0.5) * res).astype(np.float32)[:, None]
        gx = np.floor(f[0, 0] * wx + (f[0, 1] * wy + f[0, 2])).astype(np.int32)
        gy = np.floor(f[1, 0] * wx + (f[1, 1] * wy + f[1, 2])).astype(np.int32)
        inside = (gx >= 0) & (gx < w) & (gy >= 0) & (gy < h)
        v = g.cells[np.where(inside, gy, 0), np.where(inside, gx, 0)]
        occupied[top : top + rows] = inside & (v >= 65)
        free[top : top + rows] = inside & (v >= 0) & (v <= 25)
    return occupied, free


def blend(a: Pose2, b: Pose2, share: float) -> Pose2:
    turn = math.remainder(b[2] - a[2], math.tau)
    return (a[0] + share * (b[0] - a[0]), a[1] + share * (b[1] - a[1]), math.remainder(a[2] + share * turn, math.tau))


def fmt(p: Pose2) -> str:
    return f"({p[0]:.2f} m, {p[1]:.2f} m, {math.degrees(p[2]):.1f} deg)"
