"""``map_merge``: a ROS 2 node that merges the live maps of many robots with no known initial poses, a
drop-in for m-explore's ``multirobot_map_merge`` (its parameters, names and defaults; see docs/ros.md).

Run: ``python -m ogm_corners.ros`` (or the ``ogm-corners-map-merge`` script) with the usual
``--ros-args -p name:=value --params-file params.yaml``. Needs rclpy, nav_msgs and geometry_msgs: a sourced
ROS 2, or the ``ros`` extra of the package (the ``ros-jazzy-*`` wheels).
"""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
import time
from typing import Any, Dict, List, Optional, Set

import numpy as np

from .._detect import BACKENDS
from .._map import OccupancyGrid as Cells
from .live import LiveMerge, Options, Pose2, grid_of

import rclpy
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import OccupancyGrid
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String

try:  # in a ROS 2 install; not in the ros-jazzy-* wheel set
    from map_msgs.msg import OccupancyGridUpdate as GridUpdate
except ImportError:
    GridUpdate = None

GRID_TYPE = "nav_msgs/msg/OccupancyGrid"
#: A robot publishing its map more often than this a second is told (once) that only its latest is read.
FAST_HZ = 10

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
    "pose_tolerance_m": 1.0,
    "pose_tolerance_deg": 3.0,
    "settle_s": 10.0,
    "max_cells": 1 << 27,
    "robot_map_frame": "map",
}


class ConfigError(ValueError):
    """A parameter the node cannot run with: refused at start, in one line, rather than failing (or doing
    nothing) at every map."""


def config_errors(p: Dict[str, Any]) -> List[str]:
    """What is wrong with the parameters ``p`` (none: an empty list)."""
    errors = []
    if p["max_cells"] < 1:
        errors.append(f"max_cells must be 1 or more (the most cells a map may have); got {p['max_cells']}")
    if p["backend"] not in BACKENDS:
        errors.append(f"backend must be one of {', '.join(BACKENDS)}; got {p['backend']!r}")
    topic = p["robot_map_topic"]
    if not topic.strip() or "/" in topic:
        errors.append(
            "robot_map_topic must be the name of each robot's map topic within its namespace, without '/' "
            f"(as map); got {topic!r}"
        )
    return errors


def latched(depth: int = 1) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


class MapMerge(Node):
    """The ``map_merge`` node: discovers robots' map topics, merges their maps with no known initial
    poses, publishes the merged map, each robot's pose and a status document. ``ConfigError`` for
    parameters it cannot run with."""

    def __init__(self) -> None:
        # Undeclared parameters allowed and overrides declared: a params file's per-robot
        # `/robot1/map_merge/init_pose_x` keys load as they do for multirobot_map_merge.
        super().__init__(
            "map_merge",
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
        )
        # Log lines go to rosout; once closing, a worker's late line (an estimation that ended after
        # Ctrl-C) is dropped, not published through a context being shut down.
        self._log_lock = threading.Lock()
        self._closed = False
        p = {k: self._param(k, v) for k, v in {**THEIRS, **OURS}.items()}
        self.p = p
        errors = config_errors(p)
        if errors:
            raise ConfigError("; ".join(errors))
        self.live = LiveMerge(
            Options(
                growth=p["growth"],
                pose_tolerance_m=p["pose_tolerance_m"],
                pose_tolerance_deg=p["pose_tolerance_deg"],
                settle_s=p["settle_s"],
                backend=p["backend"],
                init_poses={} if p["known_init_poses"] else None,
            )
        )
        if p["estimation_confidence"] != THEIRS["estimation_confidence"]:
            self._log("info",
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
        self._warn_merged_topic()
        if GridUpdate is None:
            self._log("info",
                "map_msgs is not importable: robots' map_updates are not read, only their full maps (with "
                "a ROS 2 install, each OccupancyGridUpdate is applied to its robot's map)"
            )
        self.tf: Any = None
        try:
            import tf2_ros

            self.tf = tf2_ros.TransformBroadcaster(self)
        except ImportError:
            self._log("info",
                "tf2_ros is not importable: no world_frame -> <robot>/map transforms are published; each "
                "robot's map pose is on <robot>/map_merge/pose"
            )
        # The graph is looked at each second at least: a look costs well under a millisecond here (no
        # ROS 1 master to call), and at multirobot_map_merge's 0.05 Hz a robot missed by the first look
        # (DDS discovery takes a moment) would wait 20 s. A faster discovery_rate is honoured.
        self.create_timer(1.0 / max(p["discovery_rate"], 1.0), self.discover)
        self._first = self.create_timer(0.5, self._discover_once)
        self._input = threading.RLock()
        self._pending: Dict[str, Any] = {}
        self._rate: Dict[str, Any] = {}
        self._stop = threading.Event()
        self._status_lock = threading.Lock()
        self._workers = [
            threading.Thread(target=self._estimate_loop, name="map_merge-estimation", daemon=True),
            threading.Thread(target=self._merge_loop, name="map_merge-merging", daemon=True),
        ]
        for w in self._workers:
            w.start()

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
            self._log("error",
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

    def _warn_merged_topic(self) -> None:
        """Says when the merged map's topic is where a robot's map would be: that robot is never merged
        (the node must not read its own output)."""
        robot, _, last = self._merged_topic.rpartition("/")
        if robot and last == self.p["robot_map_topic"] and self.p["robot_namespace"] in self._merged_topic:
            self._log(
                "warning",
                f"merged_map_topic {self._merged_topic} is robot {robot}'s map topic: that robot's map is not "
                "read (it would be this node's own output); set merged_map_topic to a topic of its own",
            )

    def _log(self, level: str, text: str) -> None:
        """Logs ``text`` at ``level`` (``debug``, ``info``, ``warning``, ``error``) unless the node is
        closing."""
        with self._log_lock:
            if self._closed:
                return
            # One call site a severity: rclpy refuses a site whose severity changes between calls.
            log = self.get_logger()
            if level == "debug":
                log.debug(text)
            elif level == "info":
                log.info(text)
            elif level == "warning":
                log.warning(text)
            else:
                log.error(text)

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
            if GridUpdate is not None:
                updates = f"{robot}/{self.p['robot_map_updates_topic']}"
                # Volatile: an update is only meaningful after the full map it patches (which is latched).
                self.subs[updates] = self.create_subscription(
                    GridUpdate, updates, lambda msg, r=robot: self.on_update(r, msg), 10
                )
            self.pose_pubs[robot] = self.create_publisher(PoseStamped, f"{robot}/map_merge/pose", latched())
            self._log("info",
                f"robot {robot}: subscribed to {name} ({'transient-local' if durable else 'volatile'}, "
                f"{'reliable' if reliable else 'best-effort'})"
            )

    # ---- input ----

    def on_map(self, robot: str, msg: OccupancyGrid) -> None:
        """Keeps the message: it is read when the merged map is next drawn, so a robot publishing at
        100 Hz costs one map's conversion per merged map, and its latest map is the one used."""
        now = time.monotonic()
        with self._input:
            self._pending[robot] = msg
            start, count = self._rate.get(robot, (now, 0))
            if now - start >= 1.0:
                if count > FAST_HZ:
                    self._once(f"fast:{robot}", f"robot {robot} publishes its map {count / (now - start):.0f} times "
                                                "a second: only its latest map is read, at most merging_rate "
                                                "times a second")
                start, count = now, 0
            self._rate[robot] = (start, count + 1)

    def _read_pending(self, only: Optional[str] = None) -> None:
        """The maps kept by ``on_map`` (of robot ``only``, or all) into the merge."""
        with self._input:
            robots = [only] if only is not None else list(self._pending)
            for robot in robots:
                msg = self._pending.pop(robot, None)
                if msg is None:
                    continue
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                grid, why = grid_of(msg, self.p["max_cells"], stamp)
                if grid is None:
                    if self.bad.get(robot) != why:
                        self._log("warning", f"robot {robot}: map ignored: {why}")
                        self.bad[robot] = why
                    continue
                self.bad.pop(robot, None)
                self.live.update(robot, grid)

    def on_update(self, robot: str, msg: Any) -> None:
        self._read_pending(robot)  # the full map it patches first
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        why = self.live.patch(robot, msg.x, msg.y, msg.width, msg.height, msg.data, stamp)
        if why is not None and self.bad.get(robot) != why:
            self._log("warning", f"robot {robot}: map update ignored: {why}")
            self.bad[robot] = why

    # ---- estimation and output, off the executor's thread ----

    def _estimate_loop(self) -> None:
        """Estimation at most at ``estimation_rate``, when a map is new or has changed by ``growth``. A
        thread of its own: a long estimation never holds back the merged map."""
        period = 1.0 / max(self.p["estimation_rate"], 1e-3)
        next_estimate = 0.0
        while not self._stop.wait(0.05):
            if not self.context.ok():  # SIGINT: rclpy has shut the context; nothing can be published
                return
            if time.monotonic() < next_estimate or not self.live.needs_estimation():
                continue
            next_estimate = time.monotonic() + period
            try:
                self._log("debug", f"estimating the poses of {len(self.live.robots())} robots' maps")
                for e in self.live.estimate():
                    if e.kind in ("contradicts", "moved"):
                        self._log("warning", e.text)
                    elif e.kind in ("placed", "not_placed"):
                        self._log("info", e.text)
                self._status()
            except Exception as e:  # one bad estimation must not end the node
                if not self.context.ok():
                    return
                self._log("error", f"estimation failed: {type(e).__name__}: {e}")

    def _merge_loop(self) -> None:
        """The merged map, poses and transforms at ``merging_rate`` when a map or a pose has changed."""
        period = 1.0 / max(self.p["merging_rate"], 1e-3)
        drawn = -1
        while not self._stop.wait(0.005):
            if not self.context.ok():
                return
            self._read_pending()
            version = self.live.version
            if version == drawn:
                continue
            started = time.monotonic()
            drawn = version
            try:
                self._publish()
            except Exception as e:
                if not self.context.ok():
                    return
                self._log("error", f"merging failed: {type(e).__name__}: {e}")
            # At most merging_rate: the next one no sooner than a period after this one began.
            self._stop.wait(max(0.0, period - (time.monotonic() - started)))

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
        # The stamps and poses this map was drawn from (a map or a pose may have changed since).
        drawn = self.live.last_drawn
        poses = {r: pose for r, (_, pose) in drawn.items() if pose is not None}
        transforms = []
        for robot, pose in poses.items():
            if robot not in self.pose_pubs:
                continue
            ps = PoseStamped()
            ps.header = msg.header
            ps.pose.position.x, ps.pose.position.y = pose[0], pose[1]
            ps.pose.orientation.z, ps.pose.orientation.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
            self.pose_pubs[robot].publish(ps)
            if self.tf is not None:
                transforms.append(self._transform(msg.header, robot, pose))
        if transforms:
            self.tf.sendTransform(transforms)
        # What this merged map was drawn from: each robot's map by its header stamp (latency is measured
        # against it), on the status topic right after the map.
        self._status(merged={"stamp": msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec,
                             "maps": {r: stamp for r, (stamp, pose) in drawn.items() if pose is not None}})

    def _transform(self, header: Any, robot: str, pose: Pose2) -> Any:
        """``world_frame -> <robot>/map`` (the robot's map frame, as multirobot_map_merge's TF PR names it)."""
        t = TransformStamped()
        t.header = header
        t.child_frame_id = f"{robot.strip('/')}/{self.p['robot_map_frame']}"
        t.transform.translation.x, t.transform.translation.y = pose[0], pose[1]
        t.transform.rotation.z, t.transform.rotation.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
        return t

    def _status(self, merged: Optional[Dict[str, Any]] = None) -> None:
        """The status document: each robot placed or why not; after a merged map, what it was drawn from;
        the last estimation's use of the cache."""
        poses, reasons = self.live.poses(), self.live.reasons()
        doc: Dict[str, Any] = {
            "robots": {
                r: {"placed": r in poses, "pose": list(poses[r]) if r in poses else None, "reason": reasons.get(r)}
                for r in self.live.robots()
            },
            "estimation": self.live.last_estimation(),
        }
        if merged is not None:
            doc["merged"] = merged
        with self._status_lock:  # two threads publish it
            self.status_pub.publish(String(data=json.dumps(doc)))

    def _once(self, key: str, text: str) -> None:
        if key not in self.said:
            self.said.add(key)
            self._log("warning", text)

    def close(self) -> None:
        """Stops the workers; from now on nothing is logged (see ``_log``)."""
        with self._log_lock:
            self._closed = True
        self._stop.set()
        for w in self._workers:
            w.join(timeout=10)


def _terminated(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def main(args: Optional[list] = None) -> int:
    """Runs the node until SIGINT or SIGTERM: 0, or 2 with a one-line error for parameters it cannot run
    with."""
    # rclpy's own handlers would shut the context down at once, while a worker may still log through it
    # ("Failed to publish log message to rosout"): here a signal raises KeyboardInterrupt in the spin
    # loop, and the context is shut down once the node is closed.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, _terminated)
    node: Optional[MapMerge] = None
    executor: Optional[SingleThreadedExecutor] = None
    try:
        # A signal may come while the node is still being built (its warnings already out): that is a
        # clean stop too, so the node is built inside the same try.
        try:
            node = MapMerge()
        except ConfigError as e:
            print(f"map_merge: {e}", file=sys.stderr)
            return 2
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # Short waits: a signal's handler runs between them (nothing wakes a wait otherwise).
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        _close(node, executor)
    return 0


def _close(node: Optional["MapMerge"], executor: Optional[SingleThreadedExecutor]) -> None:
    """The node's workers stopped, then the executor, the node and rclpy's context, whichever exist."""
    if node is not None:
        try:
            node.close()
        except KeyboardInterrupt:
            pass  # a second Ctrl-C: no waiting for the workers (daemons, whose logging is off by now)
    if executor is not None:
        executor.shutdown()
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()
