"""Measures `slamesh ros2` against `slamesh run` on the same scans (docs/journal.md, "ROS 2
node"): the latency from publishing a cloud to receiving its Odometry (median and 95th
percentile) beside the pipeline's own time a frame, the CPU time and peak memory the node
takes over `run`, and whether 2 MB clouds at 10 Hz arrive with none lost.

Run it inside a loopback-only network namespace, as tests/ros2/run.sh runs check_node.py:

    unshare -n bash -c 'ip link set lo up; ip link set lo multicast on;
      ip route add 224.0.0.0/4 dev lo; PY tests/ros2/measure.py --slamesh BIN --python PY
      --data DIR --work DIR'
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
from check_node import Node, fail, peer  # noqa: E402


def cpu_s(pid):
    """User + system CPU seconds of a running process."""
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def peak_mb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmHWM"):
            return int(line.split()[1]) / 1024
    return 0.0


def main():
    p = argparse.ArgumentParser()
    for a in ["--slamesh", "--python", "--data", "--work"]:
        p.add_argument(a, required=True)
    args = p.parse_args()
    os.makedirs(args.work, exist_ok=True)
    rows = []
    for seq in ["00", "01", "02", "03", "04"]:
        folder = os.path.join(args.data, "kitti-mini", seq)
        run_out = os.path.join(args.work, f"run-{seq}")
        t = subprocess.run(
            ["/usr/bin/time", "-f", "%U %S %M", args.slamesh, "run", folder, "--out", run_out,
             "--preset", "kitti", "--threads", "2", "-q"],
            capture_output=True, text=True, check=True)
        user, sys_s, rss_kb = t.stderr.strip().splitlines()[-1].split()
        node = Node(args, os.path.join(args.work, f"node-{seq}", "out"))
        args_seq = argparse.Namespace(**vars(args))
        args_seq.data = args.data
        r = peer(args_seq, "scans", os.path.join(args.work, f"peer-{seq}.json"),
                 "--kitti", folder, "--free", node=node)
        node_cpu, node_peak = cpu_s(node.p.pid), peak_mb(node.p.pid)
        node.stop()
        report = json.load(open(os.path.join(node.out, "report.json")))
        frames = [f["ms"]["total"] for f in report["frames"]] if "frames" in report else []
        drops = int(r["diagnostics"][-1]["scans_dropped"]) if r["diagnostics"] else -1
        rows.append({
            "seq": seq, "scans": r["scans"], "odometry": len(r["odom"]), "dropped": drops,
            "latency_ms": r["latency_ms"], "pipeline_ms": frames,
            "run_cpu_s": float(user) + float(sys_s), "run_peak_mb": int(rss_kb) / 1024,
            "node_cpu_s": node_cpu, "node_peak_mb": node_peak,
        })
    lat = sorted(x for r in rows for x in r["latency_ms"])
    pipe = sorted(x for r in rows for x in r["pipeline_ms"])
    p95 = lambda v: v[min(len(v) - 1, round(0.95 * (len(v) - 1)))] if v else float("nan")
    out = {
        "scans": sum(r["scans"] for r in rows),
        "odometry": sum(r["odometry"] for r in rows),
        "dropped": sum(max(r["dropped"], 0) for r in rows),
        "latency_median_ms": statistics.median(lat), "latency_p95_ms": p95(lat),
        "pipeline_median_ms": statistics.median(pipe) if pipe else None,
        "pipeline_p95_ms": p95(pipe),
        "run_cpu_s": sum(r["run_cpu_s"] for r in rows),
        "node_cpu_s": sum(r["node_cpu_s"] for r in rows),
        "run_peak_mb": max(r["run_peak_mb"] for r in rows),
        "node_peak_mb": max(r["node_peak_mb"] for r in rows),
    }
    json.dump({"rows": rows, "summary": out}, open(os.path.join(args.work, "measure.json"), "w"))
    print(json.dumps(out, indent=1))
    if out["odometry"] != out["scans"]:
        fail(f"{out['scans']} scans, {out['odometry']} Odometry")


if __name__ == "__main__":
    main()
