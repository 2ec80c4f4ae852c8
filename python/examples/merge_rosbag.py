"""Merge the robots' maps recorded in a ROS bag, with no ROS install.

Reads every ``nav_msgs/OccupancyGrid`` message on the topics that match a glob pattern, keeps the
latest map of each topic, places them all at once with ``ogm_corners.merge_many`` and prints where
each map lies in the merged map. The bag is read with the pure-Python ``rosbags`` package
(``pip install rosbags``): a ROS 1 ``.bag`` file, or a ROS 2 bag folder (mcap or sqlite3 storage) or
its single ``.mcap`` / ``.db3`` file.

Usage:

    python merge_rosbag.py run.bag                          # topics /robot*/map, print the poses
    python merge_rosbag.py run_ros2/ -o merged.yaml         # also write merged.yaml + merged.pgm
    python merge_rosbag.py run.bag --topics '/tb3_*/map' -o merged.yaml --overlay merged.png

Output, one line a topic (yaw in degrees; x, y in metres in the merged map's frame, that of the first
placed topic in sorted order):

    /robot0/map  placed  group 0  x=0.000 y=0.000 yaw=0.00
    /robot1/map  placed  group 0  x=-9.379 y=21.843 yaw=-19.57
    /robot2/map  not placed: no confident alignment with any other map (...)

"Latest" is by the time the bag logged the message (its receive time), not the header stamp, which a
map publisher may leave at zero. The pattern is an ``fnmatch`` glob on the whole topic name, where
``*`` also matches ``/``.

A grid the package cannot use (a 0x0 map, say) is left out with a line saying why.

Exit status: 0 merged; 2 bad input (no such bag, fewer than two usable matching topics);
3 nothing could be placed together (as ``ogm-corners merge`` does when it declines).
"""

from __future__ import annotations

import argparse
import fnmatch
import math
import os
import struct
import sys
import tempfile
import zlib
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import ogm_corners

DEFAULT_PATTERN = "/robot*/map"

# rosbags names ROS 1 types the ROS 2 way ("nav_msgs/msg/OccupancyGrid") when it reads a ROS 1 bag;
# both spellings are accepted in case a bag or a version does otherwise.
GRID_TYPES = {"nav_msgs/msg/OccupancyGrid", "nav_msgs/OccupancyGrid"}


def fail(message: str, status: int = 2) -> int:
    """Says ``message`` on one line of stderr and returns the exit status (2: bad input, 3: declined)."""
    one_line = " ".join(message.splitlines())
    print(f"merge_rosbag: {'declined' if status == 3 else 'error'}: {one_line}", file=sys.stderr)
    return status


def latest_grids(bag_path: Any, pattern: str = DEFAULT_PATTERN) -> Dict[str, Any]:
    """The latest ``OccupancyGrid`` message of each topic matching ``pattern`` in the bag at
    ``bag_path``, as ``{topic: message}`` sorted by topic (messages as ``rosbags`` deserializes them:
    ``msg.info``, ``msg.data`` an int8 numpy array). Raises ``FileNotFoundError`` for a missing bag and
    ``rosbags.highlevel.AnyReaderError`` for one it cannot read."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    # The default typestore is only used for bags that carry no message definitions (older ROS 2
    # sqlite3 bags); ROS 1 bags and mcap files always carry them.
    with AnyReader([Path(bag_path)], default_typestore=get_typestore(Stores.LATEST)) as reader:
        connections = [
            c
            for c in reader.connections
            if c.msgtype in GRID_TYPES and fnmatch.fnmatchcase(c.topic, pattern)
        ]
        if not connections:
            return {}
        # Only the raw bytes of the newest message of each topic are kept, and only those are
        # deserialized: a long recording holds many large maps of each robot. Messages come in log
        # time order; on a tie the one read last wins.
        latest: Dict[str, Any] = {}
        for connection, timestamp, raw in reader.messages(connections=connections):
            held = latest.get(connection.topic)
            if held is None or timestamp >= held[0]:
                latest[connection.topic] = (timestamp, connection, raw)
        return {
            topic: reader.deserialize(raw, connection.msgtype)
            for topic, (_, connection, raw) in sorted(latest.items())
        }


def describe(topic: str, pose: Optional[ogm_corners.Pose], why: Optional[str]) -> str:
    """One line: the topic's place in the merged map, or why it has none."""
    if pose is None:
        return f"{topic}  not placed: {why or 'no reason given'}"
    if pose.world is not None:
        w = pose.world
        where = f"x={w.x:.3f} y={w.y:.3f} yaw={math.degrees(w.yaw):.2f}"
    else:
        where = f"theta={pose.theta_deg:.2f} tx={pose.tx:.1f} ty={pose.ty:.1f} (pixels)"
    line = f"{topic}  placed  group {pose.group}  {where}"
    if pose.copy_of:
        line += f"  (a copy of {pose.copy_of})"
    return line


def write_png(path: Any, rgb: Any) -> None:
    """Writes a (height, width, 3) uint8 array as an 8-bit RGB PNG, with the standard library only."""
    height, width, _ = rgb.shape
    rows = b"".join(b"\x00" + rgb[y].tobytes() for y in range(height))  # filter 0 on every row

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 6))
    png += chunk(b"IEND", b"")
    # Written beside the target and renamed into place: a reader never sees half a picture.
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".overlay.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(png)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def parse_args(argv: Optional[Sequence[str]]) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Merge the latest OccupancyGrid of each matching topic in a ROS 1 or ROS 2 bag.",
    )
    p.add_argument("bag", help="a ROS 1 .bag file, or a ROS 2 bag folder (or its .mcap / .db3 file)")
    p.add_argument(
        "-t", "--topics", default=DEFAULT_PATTERN, metavar="GLOB",
        help=f"fnmatch pattern of the map topics (default: {DEFAULT_PATTERN})",
    )
    p.add_argument(
        "-o", "--output", metavar="OUT.yaml",
        help="write group 0's merged map: OUT.yaml and OUT.pgm beside it (or OUT.pgm alone)",
    )
    p.add_argument("--overlay", metavar="PNG", help="write group 0's overlay picture as a PNG")
    p.add_argument(
        "--backend", default="cpu", help="backend scoring the candidates (default: cpu)",
    )
    return p.parse_args(argv)


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = parse_args(argv)
    try:
        grids = latest_grids(args.bag, args.topics)
    except ImportError as e:
        return fail(f"reading bags needs the rosbags package (pip install rosbags): {e}")
    except FileNotFoundError:
        return fail(f"{args.bag}: no such bag")
    except Exception as e:  # rosbags' reader, serde and typesys errors
        return fail(f"{args.bag}: cannot read the bag: {type(e).__name__}: {e}")

    # A grid the package refuses (say a 0x0 map published before the robot moved) is left out with
    # a line saying why; the others are merged.
    topics: List[str] = []
    maps: List[ogm_corners.Map] = []
    for topic, msg in grids.items():
        try:
            maps.append(ogm_corners.Map.from_occupancy_grid(msg))
            topics.append(topic)
        except (TypeError, ValueError) as e:
            print(f"{topic}  not used: {e}")
    if len(maps) < 2:
        found = ", ".join(topics) or "none"
        return fail(
            f"{args.bag}: need usable OccupancyGrid messages on at least two topics matching "
            f"{args.topics!r}, found {len(maps)} ({found})"
        )

    result = ogm_corners.merge_many(maps, names=topics, backend=args.backend)
    merged, poses = result
    for topic, pose, why in zip(topics, poses, result.reasons):
        print(describe(topic, pose, why))
    if merged is None:
        return fail("no two maps could be placed together with confidence", status=3)

    if result.groups > 1 and (args.output or args.overlay):
        print(f"merge_rosbag: note: {result.groups} groups; only group 0 is written", file=sys.stderr)
    # The picture is drawn before anything is written, so a failure to draw it leaves no output.
    picture = result.overlay(0) if args.overlay else None
    if args.output:
        merged.save(args.output)
        print(f"wrote {args.output}")
    if picture is not None:
        write_png(args.overlay, picture)
        print(f"wrote {args.overlay}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
