"""The map-merge node's logic without ROS: robots' growing maps in, stable world poses and a merged grid
out. The node (``ogm_corners.ros.node``) feeds it messages; tests and the replay feed it directly.

Frames: each robot's map frame (where its ``OccupancyGrid.info.origin`` lives) is placed in the world
frame by a pose (x, y, yaw: ``w = R(yaw) m + (x, y)``, metres). With no known initial poses the first
robot placed is the anchor: its map frame is the world frame. Poses are of map frames, not of grids, so a
map that grows and moves its origin (slam_toolbox, gmapping) keeps its placement.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from .._map import Map
from .._merge import merge_many

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

    @property
    def reach(self) -> float:
        """Metres from the map frame's origin to the grid's farthest corner."""
        h, w = self.cells.shape
        corners = [(0, 0), (w, 0), (0, h), (w, h)]
        m = pose_matrix(self.origin)
        return max(math.hypot(*(m @ (x * self.resolution, y * self.resolution, 1.0))[:2]) for x, y in corners)


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
class Options:
    """What the node's parameters set (the names are the node's)."""

    #: Re-estimate once a map's known cells have grown by this share since its last estimation.
    growth: float = 0.1
    #: A new estimate within this of the accepted pose refines it (smoothed); beyond, it must be seen
    #: ``confirm`` estimations in a row, agreeing with itself, before the pose moves.
    pose_tolerance_m: float = 0.5
    pose_tolerance_deg: float = 3.0
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

    def __init__(self, options: Optional[Options] = None) -> None:
        self.options = options if options is not None else Options()
        self._lock = threading.Lock()
        self._grids: Dict[str, Grid] = {}
        self._estimated_known: Dict[str, int] = {}
        self._placements: Dict[str, Placement] = {}
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

    def robots(self) -> List[str]:
        with self._lock:
            return sorted(self._grids)

    def needs_estimation(self) -> bool:
        """A robot's map is new, or has grown by ``growth`` of its known cells since it was last used."""
        with self._lock:
            for r, g in self._grids.items():
                before = self._estimated_known.get(r)
                if before is None or g.known >= before * (1.0 + self.options.growth) + 1:
                    return True
            return False

    # ---- estimation ----

    def estimate(self) -> List[Event]:
        """Places the current maps (the library's many-map placement, or the known poses) and folds the
        result into the accepted poses. Runs the heavy work without the lock."""
        with self._lock:
            snapshot = dict(self._grids)
            for r, g in snapshot.items():
                self._estimated_known[r] = g.known
        if not snapshot:
            return []
        names = sorted(snapshot)
        estimates, reasons = self._place(names, snapshot)
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
                    if r not in self._placements and self._reasons.get(r) != why:
                        events.append(Event(r, "not_placed", f"{r}: not placed: {why}"))
                    self._reasons[r] = why
                    continue
                self._reasons.pop(r, None)
                events += self._fold(r, est, snapshot[r].reach)
            self._version += 1
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

    def _place(self, names: List[str], grids: Dict[str, Grid]) -> Tuple[Dict[str, Pose2], Dict[str, str]]:
        """Each robot's map frame in the anchor's map frame, from one many-map placement."""
        if len(names) < 2:
            return {}, {n: "waiting for another robot's map" for n in names}
        maps = [
            Map.from_occupancy_grid(g.cells.reshape(-1), g.cells.shape[1], g.cells.shape[0], g.resolution, g.origin)
            for g in (grids[n] for n in names)
        ]
        many = merge_many(maps, names=names, backend=self.options.backend)
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
                    return {}, {n: reasons.get(n, reasons_anchor) for n in names}
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
                    return {}, reasons
                self._anchor = anchor
        base = np.linalg.inv(frames[anchor])
        out: Dict[str, Pose2] = {}
        for n, f in frames.items():
            if group[n] != group[anchor]:
                reasons[n] = f"placed with other maps, not with the anchor {anchor}'s"
                continue
            out[n] = matrix_pose(base @ f)
        return out, reasons

    def _fold(self, r: str, est: Pose2, reach: float) -> List[Event]:
        o = self.options
        p = self._placements.get(r)
        if p is None:
            self._placements[r] = Placement(est)
            return [Event(r, "placed", f"{r}: placed at {fmt(est)}")]
        d, deg = pose_distance(est, p.pose, reach)
        if d <= o.pose_tolerance_m and deg <= o.pose_tolerance_deg:
            p.pose = blend(p.pose, est, o.smoothing)
            p.pending, p.seen = None, 0
            return []
        if p.pending is not None:
            dp, degp = pose_distance(est, p.pending, reach)
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
        """Why each robot not placed is not (the latest reason), and what is wrong with a placed one (a
        given pose the maps contradict)."""
        with self._lock:
            out = {r: why for r, why in self._reasons.items() if r not in self._placements}
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
        Raises ValueError, before allocating anything, when the grid would be over ``max_cells``."""
        with self._lock:
            placed = [(self._grids[r], p.pose) for r, p in self._placements.items() if r in self._grids]
            if not placed and self.options.init_poses is None and len(self._grids) == 1:
                # One robot: its own map is the world until another is placed.
                only = min(self._grids, key=lambda n: self._arrival.get(n, 0))
                placed = [(self._grids[only], (0.0, 0.0, 0.0))]
        if not placed:
            return None
        res = resolution or min(g.resolution for g, _ in placed)
        # The world box of every placed grid, snapped to the resolution so cells stay put between updates.
        corners = []
        for g, pose in placed:
            h, w = g.cells.shape
            m = pose_matrix(pose) @ pose_matrix(g.origin)
            for x, y in ((0, 0), (w, 0), (0, h), (w, h)):
                corners.append((m @ (x * g.resolution, y * g.resolution, 1.0))[:2])
        c = np.array(corners)
        x0, y0 = math.floor(c[:, 0].min() / res) * res, math.floor(c[:, 1].min() / res) * res
        width = int(math.ceil((c[:, 0].max() - x0) / res))
        height = int(math.ceil((c[:, 1].max() - y0) / res))
        if width * height > max_cells:
            raise ValueError(
                f"the merged map would be {width} x {height} cells, over max_cells ({max_cells}): are the "
                "robots' origins or given poses far apart?"
            )
        cells = np.full((height, width), -1, np.int8)
        inverse = [(np.linalg.inv(pose_matrix(pose) @ pose_matrix(g.origin)), g) for g, pose in placed]
        wx = x0 + (np.arange(width) + 0.5) * res
        band = max(1, (1 << 20) // max(width, 1))  # about a million cells at a time: memory stays small
        for top in range(0, height, band):
            rows = min(band, height - top)
            wy = (y0 + (np.arange(top, top + rows) + 0.5) * res)[:, None]
            occupied = np.zeros((rows, width), bool)
            free = np.zeros((rows, width), bool)
            for m, g in inverse:
                # World cell centres into the robot's grid (nearest cell).
                gx = np.floor((m[0, 0] * wx + m[0, 1] * wy + m[0, 2]) / g.resolution).astype(np.int64)
                gy = np.floor((m[1, 0] * wx + m[1, 1] * wy + m[1, 2]) / g.resolution).astype(np.int64)
                h, w = g.cells.shape
                inside = (gx >= 0) & (gx < w) & (gy >= 0) & (gy < h)
                v = np.full(gx.shape, -1, np.int16)
                v[inside] = g.cells[gy[inside], gx[inside]]
                occupied |= v >= 65
                free |= (v >= 0) & (v <= 25)
            part = cells[top : top + rows]
            part[free] = 0
            part[occupied] = 100
        return cells, res, (x0, y0, 0.0)


def blend(a: Pose2, b: Pose2, share: float) -> Pose2:
    turn = math.remainder(b[2] - a[2], math.tau)
    return (a[0] + share * (b[0] - a[0]), a[1] + share * (b[1] - a[1]), math.remainder(a[2] + share * turn, math.tau))


def fmt(p: Pose2) -> str:
    return f"({p[0]:.2f} m, {p[1]:.2f} m, {math.degrees(p[2]):.1f} deg)"
