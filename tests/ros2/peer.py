"""A stock rclpy peer for `slamesh ros2`: it publishes a KITTI sequence's scans as
sensor_msgs/PointCloud2, listens to what the node publishes, calls its services, and writes
what it saw as JSON for tests/ros2/check_node.py to judge.

It is an rclpy node that nobody on this project wrote the middleware of: rclpy and Fast DDS
from the Python package registry (the `ros-rclpy` wheels), speaking DDS to the node.

    peer.py SCENARIO --kitti DIR --out FILE.json [--rate HZ] [--qos reliable|best_effort]

Scenarios:
- `scans`: the scans of DIR (--first to --last) at --rate, waiting for each one's Odometry
  (up to 5 s) before the next is due, with --imu ten IMU readings before each; then
  `~/save_map`; records the Odometry, the path, the mesh markers,
  the diagnostics and the topics' advertised types.
- `hostile`: malformed clouds (each kind once), then a flood of one scan at 100 Hz for 3 s,
  then one good scan; records diagnostics and the Odometry that still come.
- `initialpose`: three scans, then an `initialpose` at --pose, then the rest; records the
  Odometry and the path.
- `first_bad`: a cloud whose fields overlap (float64 x, y, z laid over float32 data) first,
  then the scans at --rate stamped at an epoch time with odd nanoseconds (what f64 seconds
  cannot hold); records the Odometry (with their stamps' integers) and the diagnostics.
- `imu_drive`: the simulated drive in --drive (`write_drive --rolling --imu HZ`: PCD scans
  with each point's time, `imu0/data.csv`) replayed as `ros2 bag play` would: each scan
  published at its stamp (its sweep's start, so before the IMU's readings over its sweep),
  each reading at its stamp plus --imu-lag seconds, every stamp moved 10 s on (the IMU reads
  from a second before the first scan); records the Odometry.
- `params`: `ros2 param`'s calls through rcl_interfaces' services: list, describe, get, set
  `publish_mesh` false (live) and `preset` (refused), get again; then three scans; records
  the answers, the Odometry and the mesh messages that came after the set.
- `sim_time`: `/clock` at 1000.25 s (a bag played with --clock), then three scans; records the
  diagnostics with their stamps.
- `idle`: subscribes to everything and never reads, for --seconds.
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Log
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, PointCloud2, PointField
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

FLOAT32 = PointField.FLOAT32
FLOAT64 = PointField.FLOAT64

# `first_bad`'s stamps: 2024-12-07 plus the scan's own time plus 7 ns.
EPOCH_NS = 1_733_560_000_000_000_007


def latched(depth):
    """A reader's QoS that also takes what a transient-local writer kept: reliable, transient
    local, the last `depth` samples."""
    return QoSProfile(
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
        history=HistoryPolicy.KEEP_LAST,
    )


def kitti_scans(folder):
    """(stamp, points N x 4 float32) of every scan in a KITTI sequence folder."""
    names = sorted(os.listdir(os.path.join(folder, "velodyne")))
    stamps = [float(l) for l in open(os.path.join(folder, "times.txt")) if l.strip()]
    for name, stamp in zip(names, stamps):
        pts = np.fromfile(os.path.join(folder, "velodyne", name), dtype=np.float32)
        yield stamp, pts.reshape(-1, 4)


def cloud(stamp, points, frame="velodyne"):
    """A PointCloud2 of x, y, z, intensity float32 points."""
    m = PointCloud2()
    m.header.stamp.sec = int(math.floor(stamp))
    m.header.stamp.nanosec = int(round((stamp - math.floor(stamp)) * 1e9))
    m.header.frame_id = frame
    m.height = 1
    m.width = len(points)
    m.fields = [
        PointField(name=n, offset=4 * k, datatype=FLOAT32, count=1)
        for k, n in enumerate(["x", "y", "z", "intensity"])
    ]
    m.is_bigendian = False
    m.point_step = 16
    m.row_step = 16 * len(points)
    m.data = points.astype(np.float32).tobytes()
    m.is_dense = True
    return m


def cloud_ns(ns, points):
    """`cloud` stamped `ns` nanoseconds since the epoch, exactly."""
    m = cloud(0.0, points)
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    return m


def overlapping(stamp, points):
    """`cloud` whose x, y and z say float64 at offsets 0, 4 and 8: laid over float32 data."""
    m = cloud(stamp, points)
    m.fields = [
        PointField(name=n, offset=4 * k, datatype=FLOAT64, count=1)
        for k, n in enumerate(["x", "y", "z"])
    ]
    return m


def timed_cloud(stamp, points):
    """A PointCloud2 of x, y, z and t (seconds after the stamp) float32 points."""
    m = cloud(stamp, points)
    m.fields = [
        PointField(name=n, offset=4 * k, datatype=FLOAT32, count=1)
        for k, n in enumerate(["x", "y", "z", "t"])
    ]
    return m


def drive_events(folder, lag):
    """(due, kind, stamp, payload) of a written drive, in the order they are due: each scan
    (its x y z t rows) at its stamp, each IMU reading ([gyro, accel]) at its stamp + `lag`."""
    stamps = [float(l) for l in open(os.path.join(folder, "times.txt")) if l.strip()]
    names = sorted(os.listdir(os.path.join(folder, "velodyne")))
    events = []
    for name, stamp in zip(names, stamps):
        raw = open(os.path.join(folder, "velodyne", name), "rb").read()
        data = raw[raw.index(b"DATA binary\n") + len(b"DATA binary\n"):]
        events.append((stamp, 0, stamp, np.frombuffer(data, dtype=np.float32).reshape(-1, 4)))
    for line in open(os.path.join(folder, "imu0", "data.csv")):
        if line.startswith("#") or not line.strip():
            continue
        v = line.split(",")
        stamp = int(v[0]) * 1e-9
        events.append((stamp + lag, 1, stamp, [float(x) for x in v[1:7]]))
    events.sort(key=lambda e: (e[0], e[1]))
    return events


def malformed(stamp, points):
    """(name, message) for each kind of bad cloud the node must skip."""
    out = []
    m = cloud(stamp, points)
    m.point_step = 8  # smaller than its fields
    out.append(("point_step smaller than its fields", m))
    m = cloud(stamp, points)
    m.data = m.data[: len(m.data) // 2]  # shorter than width * height * point_step
    out.append(("data shorter than width * height * point_step", m))
    m = cloud(stamp, points)
    m.fields = [f for f in m.fields if f.name != "z"]
    out.append(("no z", m))
    nan = np.full((1000, 4), np.nan, dtype=np.float32)
    out.append(("only NaN points", cloud(stamp, nan)))
    out.append(("an empty cloud", cloud(stamp, np.zeros((0, 4), dtype=np.float32))))
    m = cloud(stamp, points[:100])
    m.width = 2**31  # a huge width
    m.row_step = 16
    out.append(("a huge width", m))
    out.append(("an unknown frame", cloud(stamp, points, frame="camera")))
    out.append(("overlapping fields", overlapping(stamp, points)))
    return out


class Peer:
    def __init__(self, args):
        self.args = args
        self.node = rclpy.create_node("slamesh_peer")
        qos = QoSProfile(
            depth=10,
            reliability=(
                ReliabilityPolicy.BEST_EFFORT
                if args.qos == "best_effort"
                else ReliabilityPolicy.RELIABLE
            ),
            history=HistoryPolicy.KEEP_LAST,
        )
        self.points = self.node.create_publisher(PointCloud2, "points", qos)
        self.initialpose = self.node.create_publisher(
            PoseWithCovarianceStamped, "initialpose", 10
        )
        self.imu = self.node.create_publisher(Imu, "imu", 100)
        self.imu_sent = 0
        self.odom = []
        self.received_at = []
        self.paths = []
        self.markers = 0
        self.marker_points = 0
        self.marker_frames = set()
        self.marker_types = set()
        self.marker_box = [[math.inf] * 3, [-math.inf] * 3]
        self.diagnostics = []
        n = self.node
        n.create_subscription(Odometry, "odom", self.on_odom, 100)
        self.last_path = []
        n.create_subscription(Path, "path", self.on_path, 10)
        # Raw: kept as bytes while the node sends, read at the end (rclpy turns a point into a
        # Python object, too slow to keep up with a first frame's tiles).
        self.mesh_bytes = []
        n.create_subscription(
            MarkerArray, "mesh", self.mesh_bytes.append, 1000, raw=True
        )
        n.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 100)
        # The node's log lines, as `ros2 topic echo /rosout` or rqt_console takes them.
        self.rosout = []
        n.create_subscription(Log, "/rosout", self.on_rosout, latched(100))
        # As Nav2's map subscribers ask: reliable, transient local, the last one.
        self.grids = 0
        self.last_grid = None
        n.create_subscription(OccupancyGrid, "map", self.on_map, latched(1))
        self.save_map = n.create_client(Trigger, "/slamesh/save_map")

    def on_odom(self, m):
        p, q = m.pose.pose.position, m.pose.pose.orientation
        self.received_at.append(time.monotonic())
        self.odom.append(
            {
                "stamp": m.header.stamp.sec + m.header.stamp.nanosec * 1e-9,
                "stamp_ns": m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec,
                "frame": m.header.frame_id,
                "child": m.child_frame_id,
                "pose": [p.x, p.y, p.z, q.x, q.y, q.z, q.w],
                "covariance": list(m.pose.covariance),
                "twist_covariance": list(m.twist.covariance),
            }
        )

    def on_map(self, m):
        self.grids += 1
        data = np.array(m.data, dtype=np.int8)
        o = m.info.origin
        self.last_grid = {
            "frame": m.header.frame_id,
            "resolution": m.info.resolution,
            "width": m.info.width,
            "height": m.info.height,
            "origin": [o.position.x, o.position.y, o.position.z,
                       o.orientation.x, o.orientation.y, o.orientation.z, o.orientation.w],
            "cells": int(data.size),
            "values": sorted(int(v) for v in np.unique(data)),
            "free": int(np.count_nonzero(data == 0)),
            "occupied": int(np.count_nonzero(data == 100)),
        }

    def on_path(self, m):
        self.paths.append(len(m.poses))
        self.last_path = [
            {
                "stamp": p.header.stamp.sec + p.header.stamp.nanosec * 1e-9,
                "frame": p.header.frame_id,
                "xyz": [p.pose.position.x, p.pose.position.y, p.pose.position.z],
            }
            for p in m.poses
        ]

    def read_markers(self):
        for b in self.mesh_bytes:
            m = deserialize_message(b, MarkerArray)
            self.markers += len(m.markers)
            for k in m.markers:
                self.marker_points += len(k.points)
                self.marker_frames.add(k.header.frame_id)
                if k.action == 0:
                    xyz = [(q.x, q.y, q.z) for q in k.points]
                    lo = [min(v[i] for v in xyz) for i in range(3)]
                    hi = [max(v[i] for v in xyz) for i in range(3)]
                    self.marker_box = [
                        [min(a, b) for a, b in zip(self.marker_box[0], lo)],
                        [max(a, b) for a, b in zip(self.marker_box[1], hi)],
                    ]
                    self.marker_types.add(k.type)

    def on_rosout(self, m):
        self.rosout.append({"name": m.name, "level": int(m.level), "msg": m.msg})

    def on_diagnostics(self, m):
        stamp = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        for s in m.status:
            self.diagnostics.append({v.key: v.value for v in s.values} | {"level": int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else int(s.level), "stamp_ns": stamp})

    def publish_imu(self, t0, t1, n=10):
        """`n` readings stamped between two scans' stamps (after `t0`, up to `t1`)."""
        for j in range(n):
            t = t0 + (j + 1) * (t1 - t0) / n
            m = Imu()
            m.header.stamp.sec = int(math.floor(t))
            m.header.stamp.nanosec = int(round((t - math.floor(t)) * 1e9))
            m.header.frame_id = "imu"
            m.angular_velocity.z = 0.01
            m.linear_acceleration.z = 9.81
            self.imu.publish(m)
            self.imu_sent += 1

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)

    def spin_quiet(self, count, quiet, seconds):
        """Spins until `count()` has not changed for `quiet` seconds (`seconds` at most)."""
        end = time.monotonic() + seconds
        last, since = count(), time.monotonic()
        while time.monotonic() < end and time.monotonic() - since < quiet:
            rclpy.spin_once(self.node, timeout_sec=0.01)
            if count() != last:
                last, since = count(), time.monotonic()

    def spin_until(self, done, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end and not done():
            rclpy.spin_once(self.node, timeout_sec=0.01)
        return done()

    def wait_for_node(self):
        ok = self.spin_until(
            lambda: self.points.get_subscription_count() > 0
            and self.node.count_publishers("odom") > 0,
            30,
        )
        if not ok:
            sys.exit("the node did not appear within 30 s")
        self.spin_for(0.5)

    def advertised(self):
        return {
            name: types
            for name, types in self.node.get_topic_names_and_types()
            if name in ("/tf", "/odom", "/path", "/mesh", "/map", "/diagnostics", "/points")
        }

    def call_save_map(self):
        if not self.save_map.wait_for_service(timeout_sec=10):
            return {"success": False, "message": "no service"}
        future = self.save_map.call_async(Trigger.Request())
        self.spin_until(future.done, 60)
        r = future.result()
        return {"success": r.success, "message": r.message} if r else None

    def publish_scans(self, scans, rate, free=False, messages=None):
        """Each scan at `rate`, each waiting for the last one's Odometry (5 s at most) unless
        `free` (a sensor's pace, whatever the node does); `messages` in place of the scans'
        own clouds."""
        sent = []
        period = 1.0 / rate
        messages = messages or [cloud(stamp, pts) for stamp, pts in scans]
        # Odometry of scans sent before this call (a scenario may send in parts).
        before = len(self.odom)
        start = time.monotonic()
        for k, m in enumerate(messages):
            due = start + (k + 1) * period
            if self.args.imu and k > 0:
                self.publish_imu(scans[k - 1][0], scans[k][0])
            self.points.publish(m)
            sent.append(time.monotonic())
            want = before + len(sent)
            if not free:
                self.spin_until(lambda: len(self.odom) >= want, 5)
            self.spin_until(lambda: time.monotonic() >= due, period)
        return sent


def scenario_scans(peer, args):
    scans = list(kitti_scans(args.kitti))[args.first : args.last]
    peer.wait_for_node()
    sent = peer.publish_scans(scans, args.rate, args.free)
    peer.spin_until(lambda: len(peer.odom) >= len(scans), 10)
    peer.spin_quiet(lambda: len(peer.mesh_bytes), 2.0, 30)
    peer.read_markers()
    # Publication to Odometry, matched by stamp.
    sent_at = {round(stamp, 6): t for (stamp, _), t in zip(scans, sent)}
    latency = [
        (r - sent_at[round(o["stamp"], 6)]) * 1000.0
        for o, r in zip(peer.odom, peer.received_at)
        if round(o["stamp"], 6) in sent_at
    ]
    return {
        "scans": len(scans),
        "sent_stamps": [s for s, _ in scans],
        "odom": peer.odom,
        "latency_ms": latency,
        "paths": peer.paths,
        "imu_sent": peer.imu_sent,
        "mesh_messages": len(peer.mesh_bytes),
        "markers": peer.markers,
        "marker_points": peer.marker_points,
        "marker_frames": sorted(peer.marker_frames),
        "marker_types": sorted(peer.marker_types),
        "marker_box": peer.marker_box,
        "grids": peer.grids,
        "last_grid": peer.last_grid,
        "last_path": peer.last_path,
        "diagnostics": peer.diagnostics,
        "advertised": peer.advertised(),
        "save_map": peer.call_save_map(),
    }


def scenario_hostile(peer, args):
    scans = list(kitti_scans(args.kitti))
    peer.wait_for_node()
    stamp, pts = scans[0]
    peer.points.publish(cloud(stamp, pts))
    peer.spin_until(lambda: len(peer.odom) >= 1, 10)
    bad = malformed(stamps_after(scans, 1), pts)
    for _, m in bad:
        peer.points.publish(m)
        peer.spin_for(0.1)
    # A flood: one scan again and again at 100 Hz for --flood-s, stamps advancing.
    flood_stamp, flood_pts = scans[1]
    flood = 0
    end = time.monotonic() + args.flood_s
    while time.monotonic() < end:
        peer.points.publish(cloud(flood_stamp + 0.001 * flood, flood_pts))
        flood += 1
        peer.spin_for(0.01)
    peer.spin_for(3.0)
    return {
        "malformed": [n for n, _ in bad],
        "flood": flood,
        "odom": peer.odom,
        "diagnostics": peer.diagnostics,
    }


def scenario_first_bad(peer, args):
    scans = list(kitti_scans(args.kitti))[: args.last]
    peer.wait_for_node()
    peer.points.publish(overlapping(scans[0][0], scans[0][1]))
    peer.spin_for(0.3)
    stamps = [EPOCH_NS + round(stamp * 1e9) for stamp, _ in scans]
    messages = [cloud_ns(ns, pts) for ns, (_, pts) in zip(stamps, scans)]
    peer.publish_scans(scans, args.rate, messages=messages)
    peer.spin_until(lambda: len(peer.odom) >= len(scans), 10)
    peer.spin_for(1.5)
    return {"sent_ns": stamps, "odom": peer.odom, "diagnostics": peer.diagnostics,
            "rosout": peer.rosout}


def turned_z(v, degrees):
    """Vector `v` turned `degrees` about z."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]


def scenario_imu_drive(peer, args):
    shift = 10.0
    events = drive_events(args.drive, args.imu_lag)
    scans = sum(1 for e in events if e[1] == 0)
    peer.wait_for_node()
    start = time.monotonic() - events[0][0] + 0.5
    for due, kind, stamp, payload in events:
        while time.monotonic() < start + due:
            rclpy.spin_once(peer.node, timeout_sec=max(0.0, min(0.002, start + due - time.monotonic())))
        if kind == 0:
            peer.points.publish(timed_cloud(stamp + shift, payload))
        else:
            m = Imu()
            t = stamp + shift
            m.header.stamp.sec = int(math.floor(t))
            m.header.stamp.nanosec = int(round((t - math.floor(t)) * 1e9)) % 1_000_000_000
            m.header.frame_id = "imu"
            w, a = turned_z(payload[:3], -args.imu_turn), turned_z(payload[3:], -args.imu_turn)
            m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = w
            m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = a
            peer.imu.publish(m)
    peer.spin_until(lambda: len(peer.odom) >= scans, 5)
    peer.spin_for(1.0)
    return {"scans": scans, "odom": peer.odom, "diagnostics": peer.diagnostics}


def scenario_params(peer, args):
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters

    node = peer.node
    peer.wait_for_node()

    def call(kind, name, request):
        client = node.create_client(kind, f"/slamesh/{name}")
        if not client.wait_for_service(timeout_sec=10):
            sys.exit(f"no service /slamesh/{name}")
        future = client.call_async(request)
        peer.spin_until(future.done, 10)
        return future.result()

    listed = call(ListParameters, "list_parameters", ListParameters.Request()).result.names
    described = call(DescribeParameters, "describe_parameters",
                     DescribeParameters.Request(names=["imu_wait"])).descriptors

    def get(names):
        values = call(GetParameters, "get_parameters", GetParameters.Request(names=names)).values
        return [(v.type, v.bool_value, v.integer_value, v.double_value, v.string_value)
                for v in values]

    before = get(["preset", "publish_mesh", "imu_wait"])

    def set_one(name, value):
        p = Parameter(name=name, value=value)
        r = call(SetParameters, "set_parameters", SetParameters.Request(parameters=[p]))
        return [(x.successful, x.reason) for x in r.results]

    off = set_one("publish_mesh", ParameterValue(type=ParameterType.PARAMETER_BOOL,
                                                bool_value=False))
    preset = set_one("preset", ParameterValue(type=ParameterType.PARAMETER_STRING,
                                              string_value="fast"))
    after = get(["preset", "publish_mesh"])
    peer.spin_for(0.5)
    meshes_before = len(peer.mesh_bytes)
    peer.publish_scans(list(kitti_scans(args.kitti))[:3], args.rate)
    peer.spin_for(1.0)
    return {"listed": list(listed), "described": [d.name for d in described],
            "before": before, "set_mesh": off, "set_preset": preset, "after": after,
            "odom": peer.odom, "meshes_after_set": len(peer.mesh_bytes) - meshes_before}


def scenario_sim_time(peer, args):
    from rosgraph_msgs.msg import Clock

    clock = peer.node.create_publisher(Clock, "/clock", 10)
    tick = Clock()
    tick.clock.sec, tick.clock.nanosec = 1000, 250_000_000
    peer.wait_for_node()
    for _ in range(5):
        clock.publish(tick)
        peer.spin_for(0.1)
    for stamp, pts in list(kitti_scans(args.kitti))[:3]:
        clock.publish(tick)
        peer.points.publish(cloud(stamp, pts))
        want = len(peer.odom) + 1
        peer.spin_until(lambda: len(peer.odom) >= want, 5)
    peer.spin_for(1.5)
    return {"odom": peer.odom, "diagnostics": peer.diagnostics}


def stamps_after(scans, k):
    return scans[k][0] - 0.05


def scenario_initialpose(peer, args):
    scans = list(kitti_scans(args.kitti))
    peer.wait_for_node()
    peer.publish_scans(scans[:3], args.rate)
    m = PoseWithCovarianceStamped()
    m.header.frame_id = "map"
    x, y, z, qx, qy, qz, qw = args.pose
    m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = x, y, z
    o = m.pose.pose.orientation
    o.x, o.y, o.z, o.w = qx, qy, qz, qw
    peer.initialpose.publish(m)
    peer.spin_for(1.0)
    peer.publish_scans(scans[3:], args.rate)
    peer.spin_for(1.5)
    return {"odom": peer.odom, "diagnostics": peer.diagnostics, "last_path": peer.last_path}


def scenario_idle(peer, args):
    """A subscriber that never reads: subscribed to everything, it never spins."""
    time.sleep(args.seconds)
    return {}


def main():
    p = argparse.ArgumentParser()
    p.add_argument(
        "scenario",
        choices=["scans", "hostile", "initialpose", "first_bad", "imu_drive", "params",
                 "sim_time", "idle"],
    )
    p.add_argument("--kitti", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--rate", type=float, default=10.0)
    p.add_argument("--qos", choices=["reliable", "best_effort"], default="reliable")
    p.add_argument("--pose", type=float, nargs=7, default=[0, 0, 0, 0, 0, 0, 1])
    p.add_argument("--flood-s", type=float, default=3.0)
    p.add_argument("--first", type=int, default=0, help="scans: the first scan sent")
    p.add_argument("--last", type=int, default=None, help="scans: the scan after the last")
    p.add_argument("--seconds", type=float, default=30.0, help="idle: how long")
    p.add_argument("--free", action="store_true", help="scans: do not wait for each Odometry")
    p.add_argument("--imu", action="store_true", help="scans: IMU readings between the scans")
    p.add_argument("--drive", help="imu_drive: the folder write_drive wrote")
    p.add_argument("--imu-lag", type=float, default=0.0, help="imu_drive: the IMU's lag (s)")
    p.add_argument("--imu-turn", type=float, default=0.0,
                   help="imu_drive: the IMU mounted turned this many degrees about z (its "
                        "readings in its own axes)")
    args = p.parse_args()
    rclpy.init()
    peer = Peer(args)
    run = {
        "scans": scenario_scans,
        "hostile": scenario_hostile,
        "initialpose": scenario_initialpose,
        "first_bad": scenario_first_bad,
        "imu_drive": scenario_imu_drive,
        "params": scenario_params,
        "sim_time": scenario_sim_time,
        "idle": scenario_idle,
    }[args.scenario]
    result = run(peer, args)
    with open(args.out, "w") as f:
        json.dump(result, f)
    peer.node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
