#!/usr/bin/env python3
"""What a navigation map says where movers were: the share of occupied, free and unknown
cells of `map.pgm` under the movers' points of a labelled drive (SemanticKITTI `.label`
files, moving classes from 250; `write_drive --movers` writes them).

    tools/navmap_swept.py SEQUENCE RUN_DIR [RUN_DIR ...]   # needs numpy

The cells are those any moving point of any scan fell in (x, y at the reference poses in
SEQUENCE/poses.txt, identity calibration); each run's own `map.yaml` places them. Run it on a
run of the same drive without movers for the map those cells should have."""
import glob
import os
import sys

import numpy as np


def read_pgm(path):
    data = open(path, "rb").read()
    header = [l for l in data.split(b"\n")[:10] if not l.startswith(b"#")]
    width, height = map(int, header[1].split())
    return np.frombuffer(data[len(data) - width * height:], dtype=np.uint8).reshape(height, width)


def moving_points(sequence):
    poses = np.loadtxt(os.path.join(sequence, "poses.txt")).reshape(-1, 3, 4)
    out = []
    for k, scan in enumerate(sorted(glob.glob(os.path.join(sequence, "velodyne", "*.bin")))):
        points = np.fromfile(scan, dtype=np.float32).reshape(-1, 4)[:, :3].astype(np.float64)
        stem = os.path.splitext(os.path.basename(scan))[0]
        labels = np.fromfile(os.path.join(sequence, "labels", stem + ".label"), dtype=np.uint32)
        world = points @ poses[k][:, :3].T + poses[k][:, 3]
        out.append(world[(labels & 0xFFFF) >= 250])
    return np.concatenate(out)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    moving = moving_points(sys.argv[1])
    for run in sys.argv[2:]:
        grid = read_pgm(os.path.join(run, "map.pgm"))
        height, width = grid.shape
        yaml = open(os.path.join(run, "map.yaml")).read()
        origin = [float(v) for v in yaml.split("origin: [")[1].split("]")[0].split(",")]
        resolution = float(yaml.split("resolution: ")[1].split()[0])
        ix = np.floor((moving[:, 0] - origin[0]) / resolution).astype(int)
        iy = np.floor((moving[:, 1] - origin[1]) / resolution).astype(int)
        inside = (ix >= 0) & (ix < width) & (iy >= 0) & (iy < height)
        cells = np.array(sorted(set(zip(ix[inside], iy[inside]))))
        values = grid[height - 1 - cells[:, 1], cells[:, 0]]
        occupied, free = (values < 50).mean(), (values > 250).mean()
        print(f"{run}: {len(cells)} cells under movers: occupied {100 * occupied:.1f} %, "
              f"free {100 * free:.1f} %, unknown {100 * (1 - occupied - free):.1f} %")


if __name__ == "__main__":
    main()
