"""KISS-ICP on the same kitti-mini scans, timed the way `slamesh bench` times slamesh.

    pip install kiss-icp
    python3 tools/kiss_icp_compare.py ../shared/data/kitti-mini --threads 1 2 --repeat 3
    python3 tools/kiss_icp_compare.py DIR --sequence --no-kitti-correction --repeat 1

With `--sequence`, DIR is one sequence (a `velodyne` folder, `poses.txt`, `calib.txt`), such
as the simulated town written by `cargo run --release --example write_drive -- --out DIR`;
`--no-kitti-correction` leaves out KITTI's vertical-angle correction (for scans that are not
KITTI's). Each pass's total seconds are printed too: registration alone, and with reading the
files (a full run's time, to set beside `time slamesh run DIR`).

Per sequence and thread count: one warm-up pass, then `--repeat` timed passes; each pass is a
fresh KissICP (default configuration, the KITTI vertical correction its own KITTI loader
applies, no deskewing: the odometry scans carry no per-point times). The time of a scan is
`register_frame` alone (reading the file is not timed, as in `slamesh bench`). Prints the
median and 95th percentile ms per scan, and the mean consecutive-frame translation error
against the reference poses (same metric as slamesh's kitti_odometry test).
"""
import argparse
import glob
import os
import statistics
import time

import numpy as np
from kiss_icp.config import load_config
from kiss_icp.kiss_icp import KissICP
from kiss_icp.pybind import kiss_icp_pybind


def read_scan(path, kitti_correction=True):
    points = np.fromfile(path, dtype=np.float32).reshape((-1, 4))[:, :3].astype(np.float64)
    if not kitti_correction:
        return points
    return np.asarray(kiss_icp_pybind._correct_kitti_scan(kiss_icp_pybind._Vector3dVector(points)))


def reference_lidar_poses(seq_dir):
    calib = {}
    for line in open(os.path.join(seq_dir, "calib.txt")):
        key, _, values = line.partition(":")
        calib[key.strip()] = np.array([float(v) for v in values.split()])
    tr = np.eye(4)
    tr[:3, :4] = calib["Tr"].reshape(3, 4)
    poses = []
    for line in open(os.path.join(seq_dir, "poses.txt")):
        p = np.eye(4)
        p[:3, :4] = np.array([float(v) for v in line.split()]).reshape(3, 4)
        poses.append(np.linalg.inv(tr) @ p @ tr)
    return poses


def consecutive_error_cm(estimate, reference):
    errors = []
    for i in range(1, len(estimate)):
        d_est = np.linalg.inv(estimate[i - 1]) @ estimate[i]
        d_ref = np.linalg.inv(reference[i - 1]) @ reference[i]
        errors.append(np.linalg.norm((np.linalg.inv(d_ref) @ d_est)[:3, 3]) * 100)
    return sum(errors) / len(errors)


def run(scans, threads):
    config = load_config(None)
    config.data.deskew = False
    config.registration.max_num_threads = threads
    odometry = KissICP(config)
    ms, poses = [], []
    for points in scans:
        start = time.perf_counter()
        odometry.register_frame(points, np.array([]))
        ms.append((time.perf_counter() - start) * 1e3)
        poses.append(odometry.last_pose.copy())
    return ms, poses


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("kitti_mini")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--sequence", action="store_true", help="the folder is one sequence")
    parser.add_argument("--no-kitti-correction", action="store_true")
    args = parser.parse_args()
    print("| sequence | threads | median ms | p95 ms | translation [cm] | pass s | pass with reading s |")
    print("|---|---|---|---|---|---|---|")
    sequences = [args.kitti_mini] if args.sequence else sorted(
        glob.glob(os.path.join(args.kitti_mini, "[0-9][0-9]")))
    for seq_dir in sequences:
        paths = sorted(glob.glob(os.path.join(seq_dir, "velodyne", "*.bin")))
        start = time.perf_counter()
        scans = [read_scan(p, not args.no_kitti_correction) for p in paths]
        read_s = time.perf_counter() - start
        reference = reference_lidar_poses(seq_dir)
        for threads in args.threads:
            run(scans, threads)  # warm-up
            timed, passes = [], []
            for _ in range(args.repeat):
                start = time.perf_counter()
                ms, poses = run(scans, threads)
                passes.append(time.perf_counter() - start)
                timed.extend(ms)
            timed.sort()
            p95 = timed[min(len(timed) - 1, round((len(timed) - 1) * 0.95))]
            error = consecutive_error_cm(poses, reference)
            pass_s = statistics.median(passes)
            print(f"| {os.path.basename(os.path.normpath(seq_dir))} | {threads} "
                  f"| {statistics.median(timed):.1f} | {p95:.1f} | {error:.2f} | {pass_s:.1f} "
                  f"| {pass_s + read_s:.1f} |")


if __name__ == "__main__":
    main()
