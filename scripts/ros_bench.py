#!/usr/bin/env python3
"""Benchmark of the map_merge node (python -m ogm_corners.ros) on the real buildings of
../shared/merge-pairs: robots in their own processes publish growing maps (``ogm_corners.ros.scenario``:
exploration along the free space, the grid growing and its origin moving) of a building's maps, and this
script listens to the node and measures, per scenario:

- first merged map: seconds from the first robot map sent to the first merged map received;
- placement delay: for each robot, seconds from the moment its overlap suffices (the library's many-map
  placement of every robot's maps as published so far places it right with another robot, checked offline
  before the run) to the node's first status that places it right;
- latency: seconds from a placed robot's map update (its header stamp) to the first merged map drawn from
  it (the status the node publishes after each merged map names the stamps drawn), median and p90;
- CPU: the node process's CPU seconds over the run's wall seconds (1.0 = one core busy);
- pose jumps (a placed robot's pose moving more than the node's tolerance between two statuses: its map's
  cells by more than 1 m RMS, or a turn of more than 3 deg)
  and wrong placements (a pair of robots placed together that fails the pairs.json success test) over the
  whole exploration: targets 0.

Run with the Python test environment (scripts/test.sh makes it): ``target/python-venv/bin/python
scripts/ros_bench.py [--scenario F5:4 ...] [--period 2] [--stages 10] [--json OUT]``. Prints a markdown
table. Not part of the tests: it takes minutes and measures time.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("OGM_MERGE_PAIRS_DIR") or ROOT.parent / "shared" / "merge-pairs")
RES = 0.05
TOL_M, TOL_DEG = 1.0, 3.0  # the node's default pose tolerance


def robot(args) -> int:
    """One simulated robot: publishes its stages at their times, then keeps the last latched."""
    import rclpy
    from builtin_interfaces.msg import Time
    from nav_msgs.msg import OccupancyGrid
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from ogm_corners._map import OccupancyGrid as Cells

    data = np.load(args.stages_file)
    rclpy.init()
    node = rclpy.create_node(f"fake_{args.name}")
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    pub = node.create_publisher(OccupancyGrid, f"/{args.name}/map", qos)
    msgs = []
    for k in range(int(data["count"])):
        crop, origin = data[f"cells{k}"], tuple(data[f"origin{k}"])
        m = Cells(crop.reshape(-1), crop.shape[1], crop.shape[0], RES, origin).fill(OccupancyGrid())
        m.header.frame_id = "map"
        msgs.append(m)
    print("ready", flush=True)
    for k, m in enumerate(msgs):
        at = args.t0 + k * args.period
        time.sleep(max(0.0, at - time.time()))
        now = time.time()
        m.header.stamp = Time(sec=int(now), nanosec=int((now % 1) * 1e9))
        m.info.map_load_time = m.header.stamp
        pub.publish(m)
        print(f"sent {k} {now:.6f}", flush=True)
    try:
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.5)
    except KeyboardInterrupt:
        pass
    return 0


def load_truth():
    truth = json.loads((SHARED / "pairs.json").read_text())
    return {(p["src"], p["dst"]): p for p in truth["pairs"]}


def wrong_pairs(poses, pairs, heights):
    """The pairs of placed robots that fail the success test: [(src, dst, rot error, rms, limit)]."""
    out = []
    for (src, dst), p in pairs.items():
        if src in poses and dst in poses:
            off, rms = pair_errors(poses[src], poses[dst], p, (heights[src], heights[dst]), RES)
            if off > p["rot_limit_deg"] or rms > p["rms_limit_px"]:
                out.append((src, dst, round(off, 2), round(rms, 1), round(p["rms_limit_px"], 1)))
    return out


def right(r, poses, pairs, heights):
    """Robot ``r`` is placed with at least one other robot it has a true pair with, and every such pair
    passes the success test."""
    others = [o for o in poses if o != r and (r, o) in pairs]
    return r in poses and bool(others) and not wrong_pairs({k: poses[k] for k in [r, *others]}, pairs, heights)


def offline_sufficient(names, stages, pairs, heights):
    """For each robot, the first stage at which the library's many-map placement of every robot's maps at
    that stage places it right (None: never), by the same world convention as the node."""
    import ogm_corners as oc

    first = {}
    for k in range(len(stages[names[0]])):
        maps = [oc.Map.from_occupancy_grid(c.reshape(-1), c.shape[1], c.shape[0], RES, o)
                for c, o in (stages[n][k] for n in names)]
        many = oc.merge_many(maps, names=names)
        poses = {}
        for n, p in zip(names, many.poses):
            if p is not None and p.world is not None:
                m = p.world.matrix
                poses[n] = (m[0, 2], m[1, 2], math.atan2(m[1, 0], m[0, 0]))
        groups = {n: p.group for n, p in zip(names, many.poses) if p is not None}
        for n in names:
            same = {o: poses[o] for o in poses if groups.get(o) == groups.get(n)}
            if n not in first and n in same and right(n, same, pairs, heights):
                first[n] = k
    return first


def scenario(building: str, n: int, args, domain: int) -> dict:
    import ogm_corners as oc
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    names = sorted(p.stem for p in (SHARED / "maps").glob(f"{building}_*.png"))[:n]
    if len(names) < n:
        raise SystemExit(f"{building} has {len(names)} maps, not {n}")
    pairs = {k: v for k, v in load_truth().items() if k[0] in names and k[1] in names}
    shares = [(k + 1) / args.stages for k in range(args.stages)]
    stages, heights, spread = {}, {}, {}
    tmp = Path(tempfile.mkdtemp(prefix="ros_bench_"))
    for name in names:
        g = oc.load_map(SHARED / "maps" / f"{name}.png").with_georef(RES).to_occupancy_grid()
        cells = g.data.reshape(g.height, g.width)
        heights[name] = g.height
        # Where its cells are (the node measures a pose's change by how far they move).
        spread[name] = Grid(cells, RES, (0.0, 0.0, 0.0), 0.0).spread
        distance = geodesic(cells)
        stages[name] = [crop_known(explored(cells, distance, s), RES) for s in shares]
        arrays = {"count": len(shares)}
        for k, (c, o) in enumerate(stages[name]):
            arrays[f"cells{k}"], arrays[f"origin{k}"] = c, np.array(o)
        np.savez(tmp / f"{name}.npz", **arrays)
    t = time.perf_counter()
    suffices = offline_sufficient(names, stages, pairs, heights)
    offline = time.perf_counter() - t

    env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "PYTHONPATH": os.pathsep.join(p for p in [PACKAGE_ROOT, os.environ.get("PYTHONPATH", "")] if p)}
    os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
    t0 = time.time() + 8.0
    offsets = {name: i * args.period / n for i, name in enumerate(names)}
    robots = {name: subprocess.Popen(
        [sys.executable, __file__, "robot", name, str(tmp / f"{name}.npz"), f"{t0 + offsets[name]:.6f}",
         str(args.period)], env=env, stdout=subprocess.PIPE, text=True) for name in names}
    for name, p in robots.items():
        assert p.stdout.readline().strip() == "ready", name
    node_log = open(tmp / "node.log", "w+")
    node = subprocess.Popen([sys.executable, "-m", "ogm_corners.ros", "--ros-args", "-p", "known_init_poses:=false"],
                            env=env, stdout=node_log, stderr=subprocess.STDOUT)
    rclpy.init()
    listener = rclpy.create_node("ros_bench")
    qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    statuses = []
    listener.create_subscription(String, "/map_merge/status", lambda m: statuses.append((time.time(), json.loads(m.data))), qos)
    # The node's CPU from just before the robots start to the end.
    while time.time() < t0 - 0.5:
        rclpy.spin_once(listener, timeout_sec=0.1)
    cpu0, wall0 = cpu_seconds(node.pid), time.time()
    end = t0 + (args.stages - 1) * args.period + args.period + args.settle
    while time.time() < end:
        rclpy.spin_once(listener, timeout_sec=0.05)
    cpu1, wall1 = cpu_seconds(node.pid), time.time()
    node.send_signal(2)
    node_rc = node.wait(timeout=30)
    for p in robots.values():
        p.send_signal(2)
    sent = {}
    for name, p in robots.items():
        try:
            out, _ = p.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            # A fake robot is not the node under test: one whose DDS teardown hangs after SIGINT (seen
            # once in CI, every stage sent) is killed, and what it printed is read all the same.
            p.kill()
            out, _ = p.communicate(timeout=30)
        sent[name] = [float(line.split()[2]) for line in out.splitlines() if line.startswith("sent")]
    listener.destroy_node()
    rclpy.shutdown()

    # ---- measures ----
    first_sent = min(min(v) for v in sent.values())
    merged = [(t, s) for t, s in statuses if "merged" in s]
    first_merged = merged[0][0] - first_sent if merged else None
    # Latency of the updates of robots already placed when they were sent (before, an update waits for
    # the placement: the placement delay measures that).
    placed_since = {}
    for t, s in statuses:
        for r, v in s["robots"].items():
            if v["placed"]:
                placed_since.setdefault(r.strip("/"), t)
    latencies = []
    for name, stamps in sent.items():
        for st in stamps:
            if st < placed_since.get(name, math.inf):
                continue
            hit = next((t for t, s in merged if s["merged"]["maps"].get(f"/{name}", -1) >= st - 1e-6), None)
            if hit is not None:
                latencies.append(hit - st)
    jumps, wrong, last, placed_at = 0, {}, {}, {}
    for t, s in statuses:
        poses = {r.strip("/"): tuple(v["pose"]) for r, v in s["robots"].items() if v["placed"]}
        for r, p in poses.items():
            if r in last:
                d, deg = cells_moved(p, last[r], spread[r])
                jumps += d > TOL_M or deg > TOL_DEG
            last[r] = p
            if r not in placed_at and right(r, poses, pairs, heights):
                placed_at[r] = t
        for a, b, off, rms, limit in wrong_pairs(poses, pairs, heights):
            if a < b:
                seen = wrong.get((a, b), {"first_s": round(t - first_sent, 1), "statuses": 0, "deg": 0, "rms_px": 0})
                seen.update(statuses=seen["statuses"] + 1, deg=max(seen["deg"], off), rms_px=max(seen["rms_px"], rms),
                            limit_px=limit, last_s=round(t - first_sent, 1))
                wrong[(a, b)] = seen
    delays = {}
    for r, k in suffices.items():
        ready = t0 + offsets[r] + k * args.period  # its stage k sent (the others' stage k are sent by then)...
        ready = max(ready, max(t0 + offsets[o] + k * args.period for o in names))  # ... all of them
        delays[r] = (placed_at[r] - ready) if r in placed_at else None
    est = [s["estimation"] for _, s in statuses if s.get("estimation", {}).get("robots", 0) > 1]
    return {
        "building": building, "robots": n, "maps": names,
        "first_merged_s": first_merged,
        "placed_right": sorted(placed_at), "suffices": {r: k for r, k in suffices.items()},
        "placement_delay_s": delays,
        "latency_s": {"median": float(np.median(latencies)) if latencies else None,
                      "p90": float(np.percentile(latencies, 90)) if latencies else None,
                      "n": len(latencies), "updates": sum(len(v) for v in sent.values())},
        "cpu_share": (cpu1 - cpu0) / (wall1 - wall0),
        "jumps": jumps, "wrong_pairs": [{"pair": list(k), **v} for k, v in sorted(wrong.items())],
        "estimations": len(est), "estimation_s_median": float(np.median([e["seconds"] for e in est])) if est else None,
        # The last merged map was drawn from every robot's last map.
        "last_maps_drawn": bool(merged) and all(
            merged[-1][1]["merged"]["maps"].get(f"/{n}", -1) >= sent[n][-1] - 1e-6 for n in names),
        "offline_s": offline, "node_exit": node_rc, "period_s": args.period, "stages": args.stages,
    }


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def table(rows) -> str:
    out = ["| building, robots | first merged map | placed right (of suffices) | placement delay median / max | "
           "update to merged map median / p90 | node CPU (cores) | pose jumps | wrong pairs |",
           "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        d = [v for v in r["placement_delay_s"].values() if v is not None]
        lat = r["latency_s"]
        out.append(
            f"| {r['building']}, {r['robots']} | {r['first_merged_s']:.2f} s | {len(r['placed_right'])} "
            f"({len(r['suffices'])}) | "
            + (f"{np.median(d):.1f} / {max(d):.1f} s" if d else "-")
            + f" | {lat['median']:.2f} / {lat['p90']:.2f} s | {r['cpu_share']:.2f} | {r['jumps']} | {len(r['wrong_pairs'])} |"
        )
    return "\n".join(out)


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "robot":
        a = argparse.Namespace(name=sys.argv[2], stages_file=sys.argv[3], t0=float(sys.argv[4]),
                               period=float(sys.argv[5]))
        return robot(a)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", action="append", help="BUILDING:ROBOTS (default F5:2 F5:4 F5:8 HIH:4 KPT4A:4)")
    ap.add_argument("--period", type=float, default=2.0, help="seconds between a robot's map updates")
    ap.add_argument("--stages", type=int, default=10, help="map updates per robot")
    ap.add_argument("--settle", type=float, default=15.0, help="seconds measured after the last update")
    ap.add_argument("--json", type=Path, help="write the results here")
    args = ap.parse_args()
    if not (SHARED / "pairs.json").exists():
        print(f"ros_bench: {SHARED} is not here: the benchmark needs the real buildings", file=sys.stderr)
        return 2
    rows = []
    for i, sc in enumerate(args.scenario or ["F5:2", "F5:4", "F5:8", "HIH:4", "KPT4A:4"]):
        building, n = sc.split(":")
        rows.append(scenario(building, int(n), args, 60 + i + os.getpid() % 50))
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    machine = f"{platform.machine()}, {os.cpu_count()} cores ({platform.processor() or 'cpu'})"
    print(f"{machine}; robots update every {args.period} s, {args.stages} updates each, node defaults "
          "(merging_rate 4, estimation_rate 0.5) but known_init_poses false")
    print(table(rows))
    if args.json:
        args.json.write_text(json.dumps({"machine": machine, "rows": rows}, indent=1))
    return 0


try:  # the package as PYTHONPATH gives it (scripts/figures.py: a release build), else this tree's
    import ogm_corners  # noqa: F401
except ImportError:
    sys.path.insert(0, str(ROOT / "python"))
import ogm_corners  # noqa: E402
from ogm_corners.ros.live import Grid, cells_moved  # noqa: E402
from ogm_corners.ros.scenario import crop_known, explored, geodesic, pair_errors  # noqa: E402

#: Where the package was imported from: the robots and the node import the same one.
PACKAGE_ROOT = str(Path(ogm_corners.__file__).resolve().parent.parent)

if __name__ == "__main__":
    sys.exit(main())
