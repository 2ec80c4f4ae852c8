"""Replays the robots' map topics of a bag through the map_merge node's logic, with no ROS install.

    python -m ogm_corners.ros.replay BAG [--topics '/robot*/map'] [--period 2.0] [--growth 0.1]
                                         [-o merged.yaml] [--poses poses.json]

Every ``nav_msgs/OccupancyGrid`` message on a matching topic is fed, in the bag's time order, to the same
``LiveMerge`` the node runs (``ogm_corners.ros.live``): an estimation whenever ``--period`` seconds of bag
time have passed and a map has grown by ``--growth``, then one at the end. Each event (a robot placed,
held, moved, not placed) is printed with its bag time; then each robot's final pose (its map frame in the
world frame: the first placed robot's map frame). ``-o`` writes the merged map (yaml + pgm), ``--poses``
the poses as JSON. The bag is read with ``rosbags`` (``pip install rosbags``): a ROS 1 ``.bag``, a ROS 2 bag
folder, or its ``.mcap`` / ``.db3`` file. The robot is the topic's namespace (``/robot1/map`` -> ``/robot1``).

Exit status: 0 two or more robots placed together; 2 bad input (no such bag, fewer than two matching
topics); 3 nothing could be placed together.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import List, Optional, Sequence

from .._map import Map
from .live import LiveMerge, Options, grid_of

GRID_TYPES = {"nav_msgs/msg/OccupancyGrid", "nav_msgs/OccupancyGrid"}


def say(text: str) -> None:
    print(" ".join(text.splitlines()), flush=True)


def fail(text: str, status: int = 2) -> int:
    print(f"replay: {'declined' if status == 3 else 'error'}: {' '.join(text.splitlines())}", file=sys.stderr)
    return status


def parse(argv: Optional[Sequence[str]]) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m ogm_corners.ros.replay", description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", help="a ROS 1 .bag, a ROS 2 bag folder, or its .mcap / .db3 file")
    ap.add_argument("--topics", default="/robot*/map", help="fnmatch pattern of the map topics (default %(default)s)")
    ap.add_argument("--period", type=float, default=2.0, help="bag seconds between estimations (default 2)")
    ap.add_argument("--growth", type=float, default=0.1, help="re-estimate after this share of growth (0.1)")
    ap.add_argument("--max-cells", type=int, default=1 << 27, help="largest grid taken, cells")
    ap.add_argument("-o", "--output", help="write the merged map here (.yaml, with its .pgm beside it)")
    ap.add_argument("--poses", help="write each robot's pose here (JSON)")
    a = ap.parse_args(argv)
    if not (math.isfinite(a.period) and a.period >= 0):
        ap.error(f"--period must be 0 or more seconds, got {a.period}")
    if not (math.isfinite(a.growth) and a.growth >= 0):
        ap.error(f"--growth must be 0 or more, got {a.growth}")
    return a


def main(argv: Optional[Sequence[str]] = None) -> int:
    a = parse(argv)
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError as e:
        return fail(f"rosbags is not importable ({e}): pip install rosbags")
    if not Path(a.bag).exists():
        return fail(f"no such bag: {a.bag}")
    clock = [0.0]  # the bag's time: a first placement settles after settle_s of it
    live = LiveMerge(Options(growth=a.growth), clock=lambda: clock[0])
    bad: dict = {}
    try:
        with AnyReader([Path(a.bag)], default_typestore=get_typestore(Stores.LATEST)) as reader:
            conns = [c for c in reader.connections
                     if c.msgtype in GRID_TYPES and fnmatch.fnmatchcase(c.topic, a.topics)]
            if len({c.topic for c in conns}) < 2:
                return fail(f"fewer than two map topics match {a.topics!r} in {a.bag}")
            start, next_estimate = None, 0.0
            for conn, stamp, raw in reader.messages(connections=conns):
                t = clock[0] = stamp * 1e-9
                start = t if start is None else start
                msg = reader.deserialize(raw, conn.msgtype)
                robot = conn.topic.rsplit("/", 1)[0] or "/"
                grid, why = grid_of(msg, a.max_cells, t)
                if grid is None:
                    if bad.get(robot) != why:
                        say(f"{t - start:8.2f} s  {robot}: map ignored: {why}")
                        bad[robot] = why
                    continue
                live.update(robot, grid)
                if t >= next_estimate and live.needs_estimation():
                    next_estimate = t + a.period
                    for e in live.estimate():
                        say(f"{t - start:8.2f} s  {e.text}")
    except Exception as e:  # rosbags' reader errors: a bag it cannot read is bad input
        if type(e).__module__.startswith("rosbags"):
            return fail(f"cannot read {a.bag}: {e}")
        raise
    # The bag has ended: its maps are final, so a placement waiting to be seen again settles (a map that
    # changed at the end is estimated first, then its placement seen again settle_s of bag time later).
    for _ in range(2):
        if live.needs_estimation():
            for e in live.estimate():
                say(f"     end  {e.text}")
        clock[0] += live.options.settle_s
    poses, reasons = live.poses(), live.reasons()
    for r in live.robots():
        if r in poses:
            x, y, yaw = poses[r]
            say(f"{r}  placed  x={x:.3f} y={y:.3f} yaw={math.degrees(yaw):.2f}")
        else:
            say(f"{r}  not placed: {reasons.get(r, 'no other map to place it with')}")
    if a.poses:
        doc = {"frame": "the first placed robot's map frame", "robots": {
            r: ({"x": poses[r][0], "y": poses[r][1], "yaw": poses[r][2]} if r in poses else None)
            for r in live.robots()}, "reasons": reasons}
        target = Path(a.poses)
        fd, tmp = tempfile.mkstemp(dir=target.parent if str(target.parent) else ".", prefix=f".{target.name}.")
        with os.fdopen(fd, "w") as f:
            json.dump(doc, f, indent=2)
            f.write("\n")
        os.replace(tmp, target)
    if len(poses) < 2:
        return fail("no two robots' maps could be placed together", 3)
    if a.output:
        try:
            cells, res, origin = live.merged(a.max_cells)
        except ValueError as e:
            return fail(str(e))
        merged = Map.from_occupancy_grid(cells.reshape(-1), cells.shape[1], cells.shape[0], res, origin)
        merged.save(a.output)
        say(f"wrote {a.output}")
    return 0


def run() -> int:
    return main(sys.argv[1:])


if __name__ == "__main__":
    sys.exit(run())
