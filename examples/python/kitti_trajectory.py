"""Runs slamesh on a KITTI sequence from Python, plots the trajectory against the reference
with matplotlib, and prints the absolute trajectory error.

    pip install . matplotlib
    python examples/python/kitti_trajectory.py ../shared/data/kitti-mini/00 --plot trajectory.png

The sequence folder holds velodyne/*.bin, times.txt, and for the reference poses.txt (camera
poses) and calib.txt (its Tr, LiDAR to camera). The error is after the rigid alignment that
`slamesh eval` and evo's `-a` make (Umeyama, no scale).
"""

import argparse
import time
from pathlib import Path

import numpy as np

import slamesh


def kitti_matrices(path: Path) -> np.ndarray:
    """KITTI's 12 numbers a line (3 x 4 rows) as (N, 4, 4)."""
    rows = np.loadtxt(path, ndmin=2).reshape(-1, 3, 4)
    last = np.tile([0.0, 0.0, 0.0, 1.0], (len(rows), 1, 1))
    return np.concatenate([rows, last], axis=1)


def reference_lidar_poses(folder: Path) -> np.ndarray:
    """The reference camera poses as LiDAR poses in the first LiDAR frame: inv(Tr) P Tr."""
    tr = np.eye(4)
    for line in (folder / "calib.txt").read_text().splitlines():
        if line.startswith("Tr:"):
            tr[:3, :] = np.array(line.split()[1:], dtype=float).reshape(3, 4)
    return np.linalg.inv(tr) @ kitti_matrices(folder / "poses.txt") @ tr


def aligned_errors(estimate: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Position errors (m) after the rotation and translation that best map the estimate onto
    the reference (Umeyama without scale)."""
    e, r = estimate - estimate.mean(0), reference - reference.mean(0)
    u, _, vt = np.linalg.svd(r.T @ e)
    d = np.sign(np.linalg.det(u @ vt))
    rot = u @ np.diag([1.0, 1.0, d]) @ vt
    return np.linalg.norm(e @ rot.T - r, axis=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequence", type=Path)
    ap.add_argument("--preset", default="kitti")
    ap.add_argument("--plot", type=Path, default=Path("trajectory.png"))
    ap.add_argument("--out", type=Path, help="also write the trajectories and mesh here")
    args = ap.parse_args()

    pipeline = slamesh.Pipeline(preset=args.preset)
    started = time.perf_counter()
    for frame in slamesh.read(args.sequence):
        try:
            r = pipeline.register(frame.points, frame.times, stamp=frame.stamp)
        except slamesh.FrameError as e:
            print(f"skipped: {e}")
            continue
        print(f"frame {r.frame}: {r.status}, {r.timings['total']:.1f} ms")
    seconds = time.perf_counter() - started
    poses = pipeline.poses()
    print(f"{len(poses)} poses in {seconds:.2f} s")
    if args.out:
        pipeline.save_trajectories(args.out)
        pipeline.save_mesh(args.out / "mesh.ply")

    estimate = poses[:, :3, 3]
    reference = reference_lidar_poses(args.sequence)[pipeline.frames().astype(int), :3, 3]
    errors = aligned_errors(estimate, reference)
    print(f"ATE (RMSE, aligned): {np.sqrt(np.mean(errors**2)):.3f} m over {len(errors)} poses")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(reference[:, 0], reference[:, 1], "k--", label="reference")
    ax.plot(estimate[:, 0], estimate[:, 1], "r-", label="slamesh")
    ax.plot(*estimate[0, :2], "go", label="start")
    ax.plot(*estimate[-1, :2], "rs", label="end")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{args.sequence.name}: ATE {np.sqrt(np.mean(errors**2)):.3f} m")
    ax.legend()
    fig.savefig(args.plot, dpi=120, bbox_inches="tight")
    print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
