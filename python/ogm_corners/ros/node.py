"""``map_merge``: a ROS 2 node that merges the live maps of many robots with no known initial poses, a
drop-in for m-explore's ``multirobot_map_merge`` (its parameters, names and defaults; see docs/ros.md).

Run: ``python -m ogm_corners.ros`` (or the ``ogm-corners-map-merge`` script) with the usual
``--ros-args -p name:=value --params-file params.yaml``. Needs rclpy, nav_msgs and geometry_msgs: a sourced
ROS 2, or the ``ros`` extra of the package (the ``ros-jazzy-*`` wheels).
"""

from __future__ import annotations

import json
import math
import threading
import time
from typing import Any, Dict, Optional, Set

import numpy as np

from .._map import OccupancyGrid as Cells
from .live import LiveMerge, Options, Pose2, grid_of

import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

GRID_TYPE = "nav_msgs/msg/OccupancyGrid"

#: multirobot_map_merge's parameters and defaults (its ROS 2 port's code).
THEIRS: Dict[str, Any] = {
    "merging_rate": 4.0,
    "discovery_rate": 0.05,
    "estimation_rate": 0.5,
    "known_init_poses": True,
    "estimation_confidence": 1.0,
    "robot_map_topic": "map",
    "robot_map_updates_topic": "map_updates",
    "robot_namespace": "",
    "merged_map_topic": "map",
    "world_frame": "world",
}
#: This node's own parameters.
OURS: Dict[str, Any] = {
    "backend": "cpu",
    "growth": 0.1,
    "pose_tolerance_m": 0.5,
    "pose_tolerance_deg": 3.0,
    "max_cells": 1 << 27,
}


def latched(depth: int = 1) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


class MapMerge(Node):
    def __init__(self) -> None:
        # Undeclared parameters allowed and overrides declared: a params file's per-robot
        # `/robot1/map_merge/init_pose_x` keys load as they do for multirobot_map_merge.
        super().__init__(
            "map_merge",
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
        )
        p = {k: self._param(k, v) for k, v in {**THEIRS, **OURS}.items()}
        self.p = p
        self.live = LiveMerge(
            Options(
                growth=p["growth"],
                pose_tolerance_m=p["pose_tolerance_m"],
                pose_tolerance_deg=p["pose_tolerance_deg"],
                backend=p["backend"],
                init_poses={} if p["known_init_poses"] else None,
            )
        )
        if p["estimation_confidence"] != THEIRS["estimation_confidence"]:
            self.get_logger().info(
                "estimation_confidence is multirobot_map_merge's feature-match threshold; this node's "
                "acceptance is calibrated on real maps and does not use it"
            )
        self.merged_pub = self.create_publisher(OccupancyGrid, p["merged_map_topic"], latched())
        self.status_pub = self.create_publisher(String, "map_merge/status", latched())
        self.pose_pubs: Dict[str, Any] = {}
        self.subs: Dict[str, Any] = {}
        self.said: Set[str] = set()
        self.bad: Dict[str, str] = {}
        self._merged_topic = self.resolve_topic_name(p["merged_map_topic"])
        try:
            import tf2_ros  # noqa: F401

            self.get_logger().info("tf2_ros found, but this node publishes poses, not transforms (yet)")
        except ImportError:
            self.get_logger().info(
                "tf2_ros is not importable: no world_frame -> <robot>/map transforms are published; each "
                "robot's map pose is on <robot>/map_merge/pose"
            )
        self.create_timer(1.0 / max(p["discovery_rate"], 1e-3), self.discover)
        self._first = self.create_timer(0.5, self._discover_once)
        self._stop = threading.Event()
        self._worker = threading.Thread(target=self._work, name="map_merge-estimation", daemon=True)
        self._worker.start()

    # ---- parameters ----

    def _param(self, name: str, default: Any) -> Any:
        if not self.has_parameter(name):
            self.declare_parameter(name, default)
        v = self.get_parameter(name).value
        if v is None:
            return default
        try:
            # A yaml `4` arrives as an int where a rate is a float; "false" as a string is false.
            if isinstance(default, bool):
                if isinstance(v, str) and v.strip().lower() in ("true", "false"):
                    return v.strip().lower() == "true"
                if isinstance(v, bool):
                    return v
                raise ValueError
            out = type(default)(v)
            if isinstance(out, float) and not (math.isfinite(out) and out > 0):
                raise ValueError
            return out
        except (TypeError, ValueError):
            self.get_logger().error(
                f"parameter {name}: {v!r} is not a valid {type(default).__name__}; using {default!r}"
            )
            return default

    def _init_pose(self, robot: str) -> Optional[Pose2]:
        """``<robot>/map_merge/init_pose_{x,y,yaw}`` (multirobot_map_merge's names; z is read and unused),
        or the nested form ``robot.map_merge.init_pose_x``; metres and radians."""
        values = []
        nested = robot.strip("/").replace("/", ".")
        for axis in ("x", "y", "z", "yaw"):
            found = None
            for name in (f"{robot}/map_merge/init_pose_{axis}", f"{nested}.map_merge.init_pose_{axis}"):
                if self.has_parameter(name):
                    found = self.get_parameter(name).value
                    break
            if found is None:
                return None
            try:
                v = float(found)
            except (TypeError, ValueError):
                v = math.nan
            if not math.isfinite(v):
                self._once(f"init-bad:{robot}", f"{robot}: init_pose_{axis} is {found!r}, not a finite number: "
                                                "not merged until it is")
                return None
            values.append(v)
        return (values[0], values[1], values[3])

    # ---- discovery ----

    def _discover_once(self) -> None:
        self._first.cancel()
        self.discover()

    def discover(self) -> None:
        topic = self.p["robot_map_topic"]
        for name, types in self.get_topic_names_and_types():
            if GRID_TYPE not in types or name == self._merged_topic:
                continue
            if name.rsplit("/", 1)[-1] != topic or self.p["robot_namespace"] not in name:
                continue
            robot = name.rsplit("/", 1)[0]
            if not robot or robot in self.subs:
                continue
            if self.live.options.init_poses is not None:
                pose = self._init_pose(robot)
                if pose is None:
                    self._once(
                        f"init:{robot}",
                        f"{robot}: no initial pose (known_init_poses is true; set {robot}/map_merge/init_pose_x, "
                        "_y, _z and _yaw): not merged until it has one",
                    )
                    continue
                self.live.options.init_poses[robot] = pose
            infos = self.get_publishers_info_by_topic(name)
            if not infos:
                continue  # only subscribers so far (rviz): its publishers' QoS is known at a later discovery
            # A transient-local subscription never hears a volatile publisher, a reliable one never a
            # best-effort publisher: match what is there.
            durable = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
            reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
            qos = QoSProfile(
                history=HistoryPolicy.KEEP_LAST,
                depth=1,
                reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
            )
            self.subs[robot] = self.create_subscription(
                OccupancyGrid, name, lambda msg, r=robot: self.on_map(r, msg), qos
            )
            self.pose_pubs[robot] = self.create_publisher(PoseStamped, f"{robot}/map_merge/pose", latched())
            self.get_logger().info(
                f"robot {robot}: subscribed to {name} ({'transient-local' if durable else 'volatile'}, "
                f"{'reliable' if reliable else 'best-effort'})"
            )

    # ---- input ----

    def on_map(self, robot: str, msg: OccupancyGrid) -> None:
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        grid, why = grid_of(msg, self.p["max_cells"], stamp)
        if grid is None:
            if self.bad.get(robot) != why:
                self.get_logger().warning(f"robot {robot}: map ignored: {why}")
                self.bad[robot] = why
            return
        self.bad.pop(robot, None)
        self.live.update(robot, grid)

    # ---- estimation and output, off the executor's thread ----

    def _work(self) -> None:
        next_estimate = next_merge = 0.0
        drawn = -1
        period = 1.0 / max(self.p["merging_rate"], 1e-3)
        while not self._stop.wait(min(period, 0.1)):
            if not self.context.ok():  # SIGINT: rclpy has shut the context; nothing can be published
                return
            now = time.monotonic()
            try:
                if now >= next_estimate and self.live.needs_estimation():
                    next_estimate = now + 1.0 / max(self.p["estimation_rate"], 1e-3)
                    for e in self.live.estimate():
                        log = self.get_logger()
                        if e.kind in ("contradicts", "moved"):
                            log.warning(e.text)
                        elif e.kind in ("placed", "not_placed"):
                            log.info(e.text)
                    self._status()
                if now >= next_merge and self.live.version != drawn:
                    next_merge = now + period
                    drawn = self.live.version
                    self._publish()
            except Exception as e:  # one bad estimation must not end the node
                if not self.context.ok():
                    return
                self.get_logger().error(f"estimation failed: {type(e).__name__}: {e}")

    def _publish(self) -> None:
        try:
            merged = self.live.merged(self.p["max_cells"])
        except ValueError as e:
            self._once("merged-size", f"{e}; not published")
            return
        if merged is None:
            return
        cells, res, origin = merged
        msg = Cells(cells.reshape(-1), cells.shape[1], cells.shape[0], float(res), origin).fill(OccupancyGrid())
        msg.header.frame_id = self.p["world_frame"]
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.info.map_load_time = msg.header.stamp
        self.merged_pub.publish(msg)
        for robot, pose in self.live.poses().items():
            if robot not in self.pose_pubs:
                continue
            ps = PoseStamped()
            ps.header = msg.header
            ps.pose.position.x, ps.pose.position.y = pose[0], pose[1]
            ps.pose.orientation.z, ps.pose.orientation.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
            self.pose_pubs[robot].publish(ps)

    def _status(self) -> None:
        poses, reasons = self.live.poses(), self.live.reasons()
        doc = {
            "robots": {
                r: {"placed": r in poses, "pose": list(poses[r]) if r in poses else None, "reason": reasons.get(r)}
                for r in self.live.robots()
            }
        }
        self.status_pub.publish(String(data=json.dumps(doc)))

    def _once(self, key: str, text: str) -> None:
        if key not in self.said:
            self.said.add(key)
            self.get_logger().warning(text)

    def close(self) -> None:
        self._stop.set()
        self._worker.join(timeout=10)


def main(args: Optional[list] = None) -> int:
    rclpy.init(args=args)
    node = MapMerge()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    except rclpy.executors.ExternalShutdownException:
        pass
    finally:
        node.close()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
