"""Drives `slamesh ros2` with a stock rclpy peer (tests/ros2/peer.py) and checks what it does.

Run it inside a network namespace of its own with only loopback (no packet may leave the
machine); tests/ros2/run.sh makes one. It needs a Python with rclpy (the `ros-rclpy` wheels).

    check_node.py --slamesh BIN --python PY --data DIR --work DIR

Checks, each printed as it passes (the first failure stops it with its reason):
1. `scans`: the kitti-mini 00 scans at 10 Hz (reliable publisher, a second subscriber that
   never reads): every scan gets an Odometry stamped with its stamp whose pose equals
   `slamesh run`'s on the same folder; IMU readings between the scans reach the run with
   their frames (not used, `use_imu:=false`: the peer's readings are not the scans' motion); the node's own trajectory file is `run`'s byte for byte; /tf, odom, path, mesh and /diagnostics are advertised with their types and carry
   what they should; `~/save_map` writes a map that `slamesh localize` loads and localizes
   in, and (the node run with `--navmap`) the scans' floor beside it, which `slamesh navmap`
   reads, and the navigation map's files when the node stops.
2. the same from a publisher that restarts halfway, best effort the second time.
3. `hostile`: malformed clouds are each skipped and counted, a 100 Hz flood drops scans
   whole (named, counted) with the node's memory under FLOOD_PEAK_MB, the closing line,
   report.json and /diagnostics agree on every message, and the node still ends cleanly with
   its outputs.
4. `initialpose`: a pose 1.1 m off relocalizes the next scan to within 5 cm of `run`'s pose.
5. `first_bad`: a first cloud whose fields overlap is refused with its reason (on the
   terminal and as a warning on `/rosout`) and decides nothing; the scans after it get
   `run`'s poses, each Odometry stamped with its scan's stamp to the nanosecond (epoch
   stamps, which f64 seconds cannot hold).
6. `imu_drive` (with --drive, a shaken rolling-sweep drive and its 200 Hz IMU that
   `write_drive` wrote): replayed as `ros2 bag play` would, each scan at its stamp (before the
   IMU's readings over its sweep), the IMU on time and then 50 ms late: the node waits for the
   readings, every scan gets its Odometry, and the trajectory is as accurate as `run`'s on the
   same folder (with `imu_wait:=0`, the node's old behaviour, ATE 11 cm against 0.4).
7. `tf_static`: a node given `lidar_in_base` publishes it on `/tf_static` and its Odometry is
   run's moved onto the robot; a second node given none takes it from there (rclpy has no
   `tf2_msgs` wheel to play the robot_state_publisher).
8. `params`: `ros2 param`'s services (rcl_interfaces, called by rclpy): the node's parameters
   listed and described with the values it runs with; `publish_mesh` set false while it runs
   (no mesh goes out after), `preset` refused with its reason.
9. `sim_time`: with `use_sim_time`, `/diagnostics` is stamped with `/clock`'s time (a bag
   played with `--clock`), and the scans' own stamps stay on Odometry.
10. `imu_tf_static` (with --drive): check 6's drive with its IMU mounted turned a quarter about
   z, its readings in its own frame `imu`, and `base_link -> imu` on `/tf_static` (a second
   node plays the robot_state_publisher): the node takes the IMU's place from there, and the
   trajectory is as accurate as `run`'s.
"""

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import time

TYPES = {
    "/tf": "tf2_msgs/msg/TFMessage",
    "/odom": "nav_msgs/msg/Odometry",
    "/path": "nav_msgs/msg/Path",
    "/mesh": "visualization_msgs/msg/MarkerArray",
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "/points": "sensor_msgs/msg/PointCloud2",
}


# The hostile check's bound on the node's resident memory through a 4 s flood of 2 MB clouds,
# and check 1's over its ten scans at 10 Hz.
FLOOD_PEAK_MB = 400
SCANS_PEAK_MB = 120


def fail(why):
    sys.exit(f"FAIL: {why}")


def ok(what):
    print(f"ok: {what}", flush=True)


def tum(path):
    """{stamp: [x y z qx qy qz qw]} of a TUM file."""
    out = {}
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        out[round(v[0], 6)] = v[1:]
    return out


class Node:
    """`slamesh ros2` in the background, its memory sampled; `stop` sends SIGINT. The IMU's
    readings are counted, not used (`use_imu:=false`): the peer's are not the scans' motion."""

    def __init__(self, args, out, extra=(), params=(), remaps=(), quiet=True):
        os.makedirs(os.path.dirname(out), exist_ok=True)
        self.log = open(out + ".log", "w")
        self.p = subprocess.Popen(
            [args.slamesh, "ros2", "--out", out, *(["-q"] if quiet else []), *extra,
             "--ros-args", "-p", "preset:=kitti", "-p", "threads:=2", "-p", "use_imu:=false",
             "-p", "map_every:=3", *(w for p in params for w in ("-p", p)),
             *(w for r in remaps for w in ("-r", r))],
            stdout=self.log, stderr=subprocess.STDOUT,
        )
        self.out = out
        self.rss = []

    def sample(self):
        try:
            for line in open(f"/proc/{self.p.pid}/status"):
                if line.startswith("VmRSS"):
                    self.rss.append(int(line.split()[1]) / 1024)
        except OSError:
            pass

    def stop(self):
        self.p.send_signal(signal.SIGINT)
        try:
            rc = self.p.wait(timeout=120)
        except subprocess.TimeoutExpired:
            self.p.kill()
            fail(f"the node did not stop within 120 s of SIGINT ({self.out}.log)")
        self.log.close()
        if rc != 0:
            fail(f"the node exited with {rc}: {open(self.out + '.log').read()[-2000:]}")
        return open(self.out + ".log").read()


def peer(args, scenario, out, *extra, node=None, background=False):
    cmd = [args.python, os.path.join(os.path.dirname(__file__), "peer.py"), scenario,
           "--kitti", os.path.join(args.data, "kitti-mini", "00"), "--out", out, *extra]
    p = subprocess.Popen(cmd)
    if background:
        return p
    while p.poll() is None:
        if node:
            node.sample()
        time.sleep(0.25)
    if p.returncode != 0:
        fail(f"the peer ({scenario}) failed with {p.returncode}")
    return json.load(open(out))


def same_poses(odom, reference, what):
    if len(odom) != len(reference):
        fail(f"{what}: {len(odom)} Odometry messages for {len(reference)} scans")
    for o in odom:
        ref = reference.get(round(o["stamp"], 6))
        if ref is None:
            fail(f"{what}: an Odometry stamped {o['stamp']} matches no scan")
        worst = max(abs(a - b) for a, b in zip(o["pose"], ref))
        if worst > 2e-9:
            fail(f"{what}: the pose at {o['stamp']} differs from run's by {worst}")
        if o["frame"] != "odom" or o["child"] != "base_link":
            fail(f"{what}: frames {o['frame']} -> {o['child']}")


def check_scans(args, reference, run_mesh):
    node = Node(args, os.path.join(args.work, "scans", "out"), ["--navmap"])
    idle = peer(args, "idle", os.path.join(args.work, "idle.json"), "--seconds", "8",
                background=True)
    r = peer(args, "scans", os.path.join(args.work, "scans.json"), "--imu", node=node)
    log = node.stop()
    idle.wait()
    same_poses(r["odom"], reference, "reliable 10 Hz")
    ok(f"{len(r['odom'])} scans at 10 Hz, each with an Odometry equal to run's "
       f"(latency median {sorted(r['latency_ms'])[len(r['latency_ms']) // 2]:.0f} ms, "
       f"95th percentile {sorted(r['latency_ms'])[int(0.95 * (len(r['latency_ms']) - 1))]:.0f} ms; "
       f"resident memory at most {max(node.rss, default=0):.0f} MB)")
    # The node's peak over these ten scans, bounded near today's: 93 to 107 MB in eight runs
    # here (`slamesh run --navmap` on the same scans: 46 MB; the rest is RustDDS's: the
    # clouds' fragment buffers and the writers' unacknowledged messages).
    if max(node.rss, default=0) > SCANS_PEAK_MB:
        fail(f"resident memory over ten scans past {SCANS_PEAK_MB} MB: {max(node.rss)}")
    covs = [o["covariance"] for o in r["odom"][1:]]
    if not all(c[0] > 0 and c[35] > 0 and abs(c[1] - c[6]) < 1e-12 for c in covs):
        fail("a registered scan's covariance is not positive and symmetric")
    # The velocity's from the second registered scan on (the first scan is not registered).
    twists = [o["twist_covariance"] for o in r["odom"][2:]]
    if not all(c[0] > 0 and c[35] > 0 and abs(c[1] - c[6]) < 1e-12 for c in twists):
        fail(f"a velocity's covariance is not positive and symmetric: {twists[:1]}")
    ok("covariances of the poses and the velocities positive and symmetric")
    with open(os.path.join(node.out, "poses_tum.txt")) as a, open(args.run_tum) as b:
        if a.read() != b.read():
            fail("the node's poses_tum.txt differs from run's")
    ok("the node's poses_tum.txt is run's byte for byte")
    for topic, t in TYPES.items():
        if r["advertised"].get(topic) != [t]:
            fail(f"{topic} advertised as {r['advertised'].get(topic)}, not {t}")
    ok("topics advertised with their types: " + ", ".join(sorted(TYPES)))
    path = r["last_path"]
    if len(path) != len(reference) or any(p["frame"] != "map" for p in path):
        fail(f"the last path has {len(path)} poses for {len(reference)} scans")
    for p in path:
        ref = reference[round(p["stamp"], 6)]
        if max(abs(a - b) for a, b in zip(p["xyz"], ref[:3])) > 1e-6:
            fail(f"the path's pose at {p['stamp']} is not run's")
    ok("path: every pose, in map")
    box = r["marker_box"]
    lo, hi = run_mesh
    # Markers show layers as they were when sent; the final mesh is welded from the last
    # ones: the same place, within a cell.
    inside = all(lo[i] - 1.0 <= box[0][i] and box[1][i] <= hi[i] + 1.0 for i in range(3))
    if not (r["markers"] > 0 and r["marker_points"] % 3 == 0 and inside
            and r["marker_frames"] == ["map"] and r["marker_types"] == [11]):
        fail(f"mesh markers: {r['markers']} markers, {r['marker_points']} points, frames "
             f"{r['marker_frames']}, types {r['marker_types']}, box {box} vs the mesh's {run_mesh}")
    ok(f"mesh: {r['markers']} triangle-list markers, {r['marker_points'] // 3} triangles, "
       "in map, within a metre of the final mesh's bounds")
    check_grid(r, path)
    d = r["diagnostics"]
    if not d or any(x["scans_dropped"] != "0" or x["messages_refused"] != "0" for x in d):
        fail(f"diagnostics: {d[-1:] if d else 'none'}")
    # The process's resident memory as the kernel counts it, now and at its peak.
    resident, peak = float(d[-1]["resident_mb"]), float(d[-1]["peak_resident_mb"])
    if not 0 < resident <= peak <= SCANS_PEAK_MB:
        fail(f"diagnostics: resident memory {resident} MB, peak {peak} MB")
    ok(f"diagnostics: {len(d)} messages, no drops; resident memory {resident:.0f} MB, "
       f"peak {peak:.0f} MB")
    saved = r["save_map"]
    map_file = os.path.join(node.out, "map.slamesh")
    if not (saved and saved["success"] and os.path.isfile(map_file)):
        fail(f"~/save_map: {saved}")
    loc = os.path.join(args.work, "localize")
    subprocess.run([args.slamesh, "localize", os.path.join(args.data, "kitti-mini", "00"),
                    "--map", map_file, "--out", loc, "--threads", "2", "-q"], check=True)
    moved = tum(os.path.join(loc, "poses_tum.txt"))
    worst = max(max(abs(a - b) for a, b in zip(moved[t][:3], reference[t][:3])) for t in moved)
    if len(moved) != len(reference) or worst > 0.05:
        fail(f"localize in the saved map: {len(moved)} poses, {worst:.3f} m off")
    ok(f"~/save_map wrote a map that localize uses ({worst * 100:.1f} cm from run's poses); "
       f"the node said: {saved['message']}")
    # With --navmap: the scans' floor beside the saved map, which `slamesh navmap` reads, and
    # the navigation map written when the node stopped.
    grid = os.path.join(args.work, "saved-grid")
    subprocess.run([args.slamesh, "navmap", map_file, "--out", grid, "-q"], check=True)
    cells = json.load(open(os.path.join(grid, "navmap.json")))["scans_floor_cells"]
    floor = os.path.join(node.out, "map.floor")
    written = os.path.isfile(os.path.join(node.out, "map.yaml"))
    if not (os.path.isfile(floor) and cells > 0 and written):
        fail(f"--navmap: floor file {os.path.isfile(floor)}, {cells} cells of it read, "
             f"map.yaml at the end {written}")
    ok(f"--navmap: the scans' floor beside the saved map, {cells} cells read by slamesh navmap; "
       "the navigation map written at the end")
    report = json.load(open(os.path.join(node.out, "report.json")))
    taken = report["summary"]["input"]["imu_readings"]
    with_frames = sum(f.get("samples", 0) for f in report["frames"])
    if taken != r["imu_sent"] or with_frames < r["imu_sent"] - 10:
        fail(f"imu: {r['imu_sent']} readings sent, {taken} taken, {with_frames} with frames")
    ok(f"imu: {taken} readings taken, {with_frames} went with their frames")
    closing = report["summary"].get("loop_closure")
    if not closing or closing["spool_bytes"] <= 0 or closing["closures"]:
        fail(f"loop closure: on by default, keeping scans and closing nothing here: {closing}")
    ok(f"loop closure: on by default, {closing['spool_bytes']} bytes of scans kept, no loop closed")
    if "skipped:" in log or "dropped:" in log:
        fail("the node skipped a message of a well-formed run")


def check_grid(r, path):
    """`map`: OccupancyGrids as Nav2 reads them (made every third scan on the node's own
    thread, published with the scan after: how many arrive while the peer listens depends on
    the machine), the last one whole: its cells the info's width times height, each -1, 0 or
    100, free street and occupied surroundings, in `map` at 0.1 m, the robot's path on it."""
    g = r["last_grid"]
    if r["grids"] < 1 or g is None:
        fail(f"map: {r['grids']} occupancy grids")
    ox, oy = g["origin"][:2]
    res, w, h = g["resolution"], g["width"], g["height"]
    on_grid = all(ox <= p["xyz"][0] <= ox + w * res and oy <= p["xyz"][1] <= oy + h * res
                  for p in path)
    if not (g["frame"] == "map" and abs(res - 0.1) < 1e-6 and g["cells"] == w * h
            and set(g["values"]) <= {-1, 0, 100} and g["free"] > 1000
            and g["occupied"] > 100 and on_grid):
        fail(f"map: the last grid {g}")
    ok(f"map: {r['grids']} occupancy grids, the last {w} x {h} cells of {res:.2f} m in map, "
       f"{g['free']} free, {g['occupied']} occupied, the path on it")


def check_other_publishers(args, reference):
    node = Node(args, os.path.join(args.work, "restart", "out"))
    first = peer(args, "scans", os.path.join(args.work, "restart1.json"), "--last", "5")
    second = peer(args, "scans", os.path.join(args.work, "restart2.json"), "--first", "5",
                  "--qos", "best_effort")
    node.stop()
    same_poses(first["odom"] + second["odom"], reference, "a publisher that restarts")
    ok("a publisher that restarts halfway, best effort the second time: every scan, the "
       "same poses")


def check_hostile(args):
    node = Node(args, os.path.join(args.work, "hostile", "out"))
    r = peer(args, "hostile", os.path.join(args.work, "hostile.json"), "--flood-s", "4",
             node=node)
    log = node.stop()
    last = r["diagnostics"][-1]
    if int(last["messages_refused"]) != len(r["malformed"]):
        fail(f"{len(r['malformed'])} malformed clouds, {last['messages_refused']} refused")
    for reason in ["lies past point_step", "fewer than", "no x, y and z", "empty cloud", "row_step",
                   "not the scans'", "overlap: not a point layout"]:
        if reason not in log:
            fail(f"no message in the node's log says {reason!r}")
    ok(f"malformed clouds ({', '.join(r['malformed'])}): each skipped with its reason, counted")
    dropped = int(last["scans_dropped"])
    if dropped == 0 or "dropped: the pipeline is behind" not in log:
        fail(f"a {r['flood']}-scan flood at 100 Hz dropped nothing: {last}")
    # The flood's peak, bounded near today's: 356 to 360 MB in four runs here (RustDDS keeps up
    # to 128 clouds whose fragments it lost, 2 MB each; the mesh and path writers keep at most
    # node.rs's UNACKED messages a reader has not acknowledged), 474 to 495 MB before that
    # bound, 601 to 605 MB at f4c47a3, whose points topic's cache kept 64 clouds.
    rss = node.rss
    if not rss or max(rss) > FLOOD_PEAK_MB:
        fail(f"memory through the flood past {FLOOD_PEAK_MB} MB: {rss}")
    ok(f"a flood of {r['flood']} scans at 100 Hz: {dropped} dropped whole and named, "
       f"peak memory {max(rss):.0f} MB (at most {FLOOD_PEAK_MB})")
    # The closing line, report.json and /diagnostics agree on every message.
    report = json.load(open(os.path.join(node.out, "report.json")))
    counts, summary = report["summary"]["input"], report["summary"]
    line = next((l for l in log.splitlines() if "message(s) received:" in l), "")
    said = (f"{counts['received']} message(s) received: {summary['used']} scan(s) used, "
            f"{len(summary['skipped'])} skipped, {counts['dropped']} dropped whole (the pipeline "
            f"was behind), {counts['refused']} refused (not scans)")
    total = summary["used"] + len(summary["skipped"]) + counts["dropped"] + counts["refused"]
    if (said not in line or counts["dropped"] < dropped or counts["refused"] != len(r["malformed"])
            or total != counts["received"]):
        fail(f"the closing line {line!r} against report.json's {counts} and {dropped} dropped "
             "on /diagnostics")
    ok(f"the closing line, report.json and /diagnostics agree: {line}")
    if not os.path.isfile(os.path.join(node.out, "report.json")):
        fail("no report.json after SIGINT")
    ok("SIGINT: the outputs written")


def check_initialpose(args, reference):
    node = Node(args, os.path.join(args.work, "initialpose", "out"))
    r = peer(args, "initialpose", os.path.join(args.work, "initialpose.json"),
             "--pose", "1.0", "0", "0", "0", "0", "0", "1")
    log = node.stop()
    if "1 Relocalized" not in log:
        fail("the initialpose did not relocalize: " + log[-500:])
    worst = max(
        max(abs(a - b) for a, b in zip(p["xyz"], reference[round(p["stamp"], 6)][:3]))
        for p in r["last_path"]
    )
    if len(r["last_path"]) != len(reference) or worst > 0.05:
        fail(f"after initialpose: {len(r['last_path'])} poses, {worst:.3f} m from run's")
    ok(f"initialpose 1.1 m off: relocalized, every pose within {worst * 100:.1f} cm of run's")


def check_first_bad(args, reference):
    node = Node(args, os.path.join(args.work, "first_bad", "out"))
    r = peer(args, "first_bad", os.path.join(args.work, "first_bad.json"), node=node)
    log = node.stop()
    last = r["diagnostics"][-1] if r["diagnostics"] else {}
    if last.get("messages_refused") != "1" or "overlap: not a point layout" not in log:
        fail(f"the overlapping first cloud was not refused with its reason: {last}")
    # The refusal on /rosout too, a warning (30) in the node's name.
    said = [m for m in r["rosout"] if m["name"] == "slamesh" and m["level"] == 30
            and "overlap: not a point layout" in m["msg"]]
    if not said:
        fail(f"the refusal is not on /rosout: {r['rosout'][:5]}")
    sent, odom = r["sent_ns"], r["odom"]
    got = [o["stamp_ns"] for o in odom]
    if got != sent:
        off = [g - s for g, s in zip(got, sent)]
        fail(f"Odometry stamps are not the scans' to the nanosecond: {len(got)} for "
             f"{len(sent)} scans, off by {off} ns")
    # The scans' poses are run's, in order (their stamps moved to the epoch).
    ref = [reference[t] for t in sorted(reference)]
    worst = max(max(abs(a - b) for a, b in zip(o["pose"], p)) for o, p in zip(odom, ref))
    if worst > 2e-9:
        fail(f"after a refused first cloud, the poses differ from run's by {worst}")
    ok(f"an overlapping first cloud refused with its reason, on the terminal and /rosout; the "
       f"{len(odom)} scans after it have run's poses, each Odometry stamped with its scan's "
       "stamp to the nanosecond")


def kitti_positions(path):
    return [[float(v) for v in l.split()][3::4] for l in open(path) if l.strip()]


def ate(estimate, truth):
    """RMSE (m) of `estimate`'s positions against `truth`'s after the best rigid alignment."""
    import numpy as np

    a, b = np.array(estimate), np.array(truth)
    ca, cb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    moved = (r @ (a - ca).T).T + cb
    return float(np.sqrt(((moved - b) ** 2).sum(1).mean()))


def drive_reference(args):
    """The IMU drive's true positions and `slamesh run`'s ATE on its folder (run once, kept)."""
    if not args.drive:
        fail("no --drive: the IMU drive's checks need write_drive's folder")
    if getattr(args, "drive_reference", None) is None:
        run = os.path.join(args.work, "imu-run")
        subprocess.run([args.slamesh, "run", args.drive, "--out", run, "--threads", "2", "-q"],
                       check=True, stdout=subprocess.DEVNULL)
        truth = kitti_positions(os.path.join(args.drive, "poses.txt"))
        args.drive_reference = (truth,
                                ate(kitti_positions(os.path.join(run, "poses_kitti.txt")), truth))
    return args.drive_reference


def odom_ate(args, odom, truth):
    """ATE (m) of the node's Odometry on the IMU drive, each matched to its scan by its stamp
    (moved 10 s on by the peer)."""
    stamps = [float(l) + 10.0 for l in open(os.path.join(args.drive, "times.txt")) if l.strip()]
    index = {round(s, 6): k for k, s in enumerate(stamps)}
    ks = [index[round(o["stamp"], 6)] for o in odom]
    return ate([o["pose"][:3] for o in odom], [truth[k] for k in ks])


def check_imu_drive(args, wait=()):
    truth, run_ate = drive_reference(args)
    for lag in ["0", "0.05"]:
        node = Node(args, os.path.join(args.work, f"imu-drive-{lag}", "out"),
                    params=["preset:=default", "use_imu:=true", "map_every:=10", *wait])
        r = peer(args, "imu_drive", os.path.join(args.work, f"imu-drive-{lag}.json"),
                 "--drive", args.drive, "--imu-lag", lag, node=node)
        log = node.stop()
        odom, scans = r["odom"], r["scans"]
        if len(odom) < 0.97 * scans:
            fail(f"IMU {lag} s late: {len(odom)} Odometry for {scans} scans: {log[-1500:]}")
        node_ate = odom_ate(args, odom, truth)
        if node_ate > 1.2 * run_ate + 0.001:
            fail(f"IMU {lag} s late: ATE {node_ate:.4f} m against run's {run_ate:.4f} m")
        late = r["diagnostics"][-1]["imu_late"] if r["diagnostics"] else "?"
        ok(f"a shaken drive replayed with each scan at its stamp, the IMU {lag} s late: "
           f"{len(odom)} of {scans} scans with Odometry, ATE {node_ate * 100:.2f} cm "
           f"(run {run_ate * 100:.2f} cm), {late} scans ran before the IMU covered them")


def matrix(pose):
    """4 x 4 of [x y z qx qy qz qw]."""
    import numpy as np

    x, y, z, qx, qy, qz, qw = pose
    r = np.array([
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
        [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
        [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
    ])
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = r, [x, y, z]
    return m


def placed_like_run(odom, reference, e):
    """The largest difference (m, or rotation-matrix entry) of each Odometry from run's pose
    of its scan moved onto the robot: E T E^-1."""
    import numpy as np

    worst = 0.0
    for o in odom:
        t = matrix(reference[round(o["stamp"], 6)])
        want = e @ t @ np.linalg.inv(e)
        worst = max(worst, float(np.abs(matrix(o["pose"]) - want).max()))
    return worst


def check_tf_static(args, reference):
    """No wheel of tf2_msgs exists for rclpy: a second node is the robot's static publisher.
    Node A is given lidar_in_base (and lidar_frame) and publishes it on /tf_static at start;
    node B, given neither and its outputs remapped, takes it from there."""
    yaw = 0.3
    a = Node(args, os.path.join(args.work, "tf-static-a", "out"),
             params=["lidar_in_base:=[0.1,0.0,0.8,0.0,0.0,0.3]", "lidar_frame:=velodyne"])
    time.sleep(1.0)
    b = Node(args, os.path.join(args.work, "tf-static-b", "out"), quiet=False,
             params=["publish_tf:=false", "publish_mesh:=false", "publish_map:=false"],
             remaps=["odom:=odom_b", "path:=path_b", "/diagnostics:=/diagnostics_b"])
    r = peer(args, "scans", os.path.join(args.work, "tf-static.json"), "--last", "5", node=a)
    a.stop()
    log_b = b.stop()
    e = matrix([0.1, 0.0, 0.8, 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
    worst = placed_like_run(r["odom"], reference, e)
    if len(r["odom"]) != 5 or worst > 1e-6:
        fail(f"lidar_in_base given: {len(r['odom'])} Odometry, {worst} from run's moved there")
    said = "the LiDAR on the robot from /tf_static: base_link -> velodyne at (0.100, 0.000, 0.800) m"
    if said not in log_b:
        fail(f"the second node did not take the first's /tf_static: {log_b[-800:]}")
    ok(f"lidar_in_base given: Odometry run's poses moved onto the robot (within {worst:.1e}), "
       "published on /tf_static; a node given none took it from there")


def check_imu_tf_static(args):
    truth, run_ate = drive_reference(args)
    # The robot: base_link -> imu, a quarter turn about z, on /tf_static (its LiDAR frame is
    # named imu; it reads no scans).
    robot = Node(args, os.path.join(args.work, "imu-tf-robot", "out"),
                 params=["lidar_in_base:=[0.0,0.0,0.0,0.0,0.0,1.5707963267948966]",
                         "lidar_frame:=imu", "publish_mesh:=false", "publish_map:=false"],
                 remaps=["points:=robot_points", "odom:=robot_odom", "path:=robot_path",
                         "/diagnostics:=/robot_diagnostics", "/tf:=/robot_tf"])
    time.sleep(1.0)
    node = Node(args, os.path.join(args.work, "imu-tf", "out"), quiet=False,
                params=["preset:=default", "use_imu:=true", "map_every:=10"])
    r = peer(args, "imu_drive", os.path.join(args.work, "imu-tf.json"), "--drive", args.drive,
             "--imu-turn", "90", node=node)
    log = node.stop()
    robot.stop()
    said = "the IMU on the LiDAR from /tf_static: base_link -> imu"
    if said not in log:
        fail(f"the node did not take the IMU's place from /tf_static: {log[-1500:]}")
    odom = r["odom"]
    node_ate = odom_ate(args, odom, truth)
    if len(odom) < 0.97 * r["scans"] or node_ate > 1.2 * run_ate + 0.001:
        fail(f"IMU turned: {len(odom)} of {r['scans']} scans, ATE {node_ate:.4f} m against "
             f"run's {run_ate:.4f} m")
    ok(f"the IMU turned a quarter on the robot, its place from /tf_static: {len(odom)} of "
       f"{r['scans']} scans, ATE {node_ate * 100:.2f} cm (run {run_ate * 100:.2f} cm)")


def check_params(args):
    node = Node(args, os.path.join(args.work, "params", "out"))
    r = peer(args, "params", os.path.join(args.work, "params.json"), node=node)
    node.stop()
    want = {"preset", "out", "threads", "queue", "publish_mesh", "imu_wait", "map_every"}
    if not want <= set(r["listed"]) or r["described"] != ["imu_wait"]:
        fail(f"parameters listed {r['listed']}, described {r['described']}")
    # (type, bool, integer, double, string): 4 string, 1 bool, 3 double.
    preset, mesh, wait = r["before"]
    if preset[0] != 4 or preset[4] != "kitti" or mesh[:2] != [1, True] or wait[3] != 0.2:
        fail(f"the parameters' values: {r['before']}")
    (ok_mesh, _), = r["set_mesh"]
    (ok_preset, why), = r["set_preset"]
    if not ok_mesh or ok_preset or "set at start only" not in why:
        fail(f"set publish_mesh: {r['set_mesh']}; set preset: {r['set_preset']}")
    if r["after"][0][4] != "kitti" or r["after"][1][1] or len(r["odom"]) != 3:
        fail(f"after the sets: {r['after']}, {len(r['odom'])} Odometry")
    if r["meshes_after_set"] != 0:
        fail(f"{r['meshes_after_set']} mesh messages after publish_mesh was set false")
    ok(f"ros2 param: {len(r['listed'])} parameters listed with their values, publish_mesh set "
       f"false live (no mesh after), preset refused: {why}")


def check_sim_time(args, reference):
    node = Node(args, os.path.join(args.work, "sim-time", "out"), params=["use_sim_time:=true"])
    r = peer(args, "sim_time", os.path.join(args.work, "sim-time.json"), node=node)
    node.stop()
    stamps = {d["stamp_ns"] for d in r["diagnostics"]}
    if not r["diagnostics"] or stamps != {1_000_250_000_000}:
        fail(f"use_sim_time: /diagnostics stamped {sorted(stamps)}, not /clock's 1000.25 s")
    if [round(o["stamp"], 6) for o in r["odom"]] != sorted(reference)[:3]:
        fail(f"use_sim_time: Odometry stamps {[o['stamp'] for o in r['odom']]}")
    ok(f"use_sim_time: {len(r['diagnostics'])} /diagnostics stamped with /clock's 1000.25 s; "
       "Odometry keeps its scans' stamps")


def mesh_bounds(ply):
    """The bounding box of a binary or ASCII PLY's vertices (x, y, z first)."""
    import numpy as np

    with open(ply, "rb") as f:
        header = []
        while True:
            line = f.readline().decode().strip()
            header.append(line)
            if line == "end_header":
                break
        n = int(next(l.split()[2] for l in header if l.startswith("element vertex")))
        props = []
        in_vertex = False
        for l in header:
            if l.startswith("element"):
                in_vertex = l.startswith("element vertex")
            elif l.startswith("property") and in_vertex:
                props.append(l.split()[1])
        sizes = {"float": 4, "double": 8, "uchar": 1, "uint8": 1, "float32": 4}
        step = sum(sizes[p] for p in props)
        data = np.frombuffer(f.read(n * step), dtype=np.uint8).reshape(n, step)
        dt = "<f8" if props[0] == "double" else "<f4"
        w = 8 if props[0] == "double" else 4
        xyz = np.stack([data[:, k * w:(k + 1) * w].copy().view(dt)[:, 0] for k in range(3)], 1)
        return xyz.min(0).tolist(), xyz.max(0).tolist()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--slamesh", required=True)
    p.add_argument("--python", required=True)
    p.add_argument("--data", required=True)
    p.add_argument("--work", required=True)
    p.add_argument("--drive", help="a drive write_drive wrote with --shaken --imu 200")
    p.add_argument("--only", help="these checks only, by number (1,2,...): for a developer")
    p.add_argument("--imu-wait", help="check 6 with this imu_wait (seconds): 0 shows the need")
    args = p.parse_args()
    only = {int(k) for k in args.only.split(",")} if args.only else set(range(1, 11))
    wait = [f"imu_wait:={args.imu_wait}"] if args.imu_wait else []
    os.makedirs(args.work, exist_ok=True)
    run = os.path.join(args.work, "run")
    subprocess.run([args.slamesh, "run", os.path.join(args.data, "kitti-mini", "00"), "--out",
                    run, "--preset", "kitti", "--threads", "2", "-q"], check=True,
                   stdout=subprocess.DEVNULL)
    args.run_tum = os.path.join(run, "poses_tum.txt")
    reference = tum(args.run_tum)
    checks = [
        lambda: check_scans(args, reference, mesh_bounds(os.path.join(run, "mesh.ply"))),
        lambda: check_other_publishers(args, reference),
        lambda: check_hostile(args),
        lambda: check_initialpose(args, reference),
        lambda: check_first_bad(args, reference),
        lambda: check_imu_drive(args, wait),
        lambda: check_tf_static(args, reference),
        lambda: check_params(args),
        lambda: check_sim_time(args, reference),
        lambda: check_imu_tf_static(args),
    ]
    for k, check in enumerate(checks, 1):
        if k in only:
            check()
    print("PASS" if len(only) == len(checks) else f"PASS (checks {sorted(only)} only)")


if __name__ == "__main__":
    main()
