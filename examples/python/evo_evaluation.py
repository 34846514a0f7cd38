"""The same evaluation through evo (https://github.com/MichaelGrupp/evo), the tool most
odometry papers report with: slamesh's TUM trajectory from Python, the reference turned into
LiDAR poses with the same stamps, then evo's APE with alignment.

    pip install . evo
    python examples/python/evo_evaluation.py ../shared/data/kitti-mini/00 --out evo-00

It writes OUT/poses_tum.txt (slamesh), OUT/reference_tum.txt, and runs
`evo_ape tum OUT/reference_tum.txt OUT/poses_tum.txt -a`, printing its table.
"""

import argparse
import subprocess
from pathlib import Path

import numpy as np

import slamesh
from kitti_trajectory import reference_lidar_poses


def rotation_to_quaternion(r: np.ndarray) -> np.ndarray:
    """A rotation matrix as (qx, qy, qz, qw)."""
    w = np.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    return np.array([x, y, z, w])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequence", type=Path)
    ap.add_argument("--preset", default="kitti")
    ap.add_argument("--out", type=Path, default=Path("evo-out"))
    args = ap.parse_args()

    pipeline = slamesh.Pipeline(preset=args.preset)
    for frame in slamesh.read(args.sequence):
        try:
            pipeline.register(frame.points, frame.times, stamp=frame.stamp)
        except slamesh.FrameError as e:
            print(f"skipped: {e}")
    pipeline.save_trajectories(args.out)

    reference = reference_lidar_poses(args.sequence)[pipeline.frames().astype(int)]
    with open(args.out / "reference_tum.txt", "w") as f:
        for stamp, m in zip(pipeline.stamps(), reference):
            q = rotation_to_quaternion(m[:3, :3])
            f.write(f"{stamp:.6f} " + " ".join(f"{v:.9f}" for v in [*m[:3, 3], *q]) + "\n")

    subprocess.run(
        ["evo_ape", "tum", str(args.out / "reference_tum.txt"), str(args.out / "poses_tum.txt"), "-a"],
        check=True,
    )


if __name__ == "__main__":
    main()
