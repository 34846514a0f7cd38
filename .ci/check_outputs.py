#!/usr/bin/env python3
"""Checks what a `slamesh demo` or `slamesh run` wrote, as CI's last steps do: every file is
well formed (trajectories of finite poses, one per frame; a PLY mesh whose size and indices
match its header; report.json with its summary; the PNG's signature and size), and the
accuracy is within a bound set from a measurement.

    check_outputs.py demo DIR FRAMES    # also compares the estimate with poses_true_kitti.txt
    check_outputs.py kitti DIR FRAMES   # also reads DIR/eval.json (`slamesh eval --json`)

Bounds: the measured value plus 15 % for legitimate change; when a change moves a figure,
update the bound in the same commit, with the new measurement and its date.
"""
import json
import math
import struct
import sys
from pathlib import Path

# Demo, seed 1, preset town, 60 frames: mean consecutive-frame translation error 0.56 cm,
# end-point error 0.016 m (measured 2026-12-01, commit 295e178).
DEMO_MEAN_STEP_M = 0.0056 * 1.15
DEMO_END_M = 0.016 * 1.15
# kitti-mini 00, preset kitti: mean consecutive-frame translation error 1.36 cm, rotation
# 0.0545 degree (measured 2026-12-01, commit 295e178; README, Accuracy and speed).
KITTI00_MEAN_STEP_M = 0.0136 * 1.15
KITTI00_MEAN_ROT_DEG = 0.0545 * 1.15


def fail(msg):
    print(f"check_outputs: {msg}", file=sys.stderr)
    sys.exit(1)


def kitti_poses(path, frames):
    rows = [line.split() for line in Path(path).read_text().splitlines() if line.strip()]
    if len(rows) != frames:
        fail(f"{path}: {len(rows)} poses for {frames} frames")
    poses = []
    for i, r in enumerate(rows):
        v = [float(x) for x in r]
        if len(v) != 12 or not all(math.isfinite(x) for x in v):
            fail(f"{path}: line {i + 1} is not 12 finite numbers")
        poses.append([v[0:4], v[4:8], v[8:12]])
    return poses


def inverse(p):
    r = [[p[j][i] for j in range(3)] for i in range(3)]
    t = [-sum(r[i][k] * p[k][3] for k in range(3)) for i in range(3)]
    return [r[i] + [t[i]] for i in range(3)]


def compose(a, b):
    return [
        [sum(a[i][k] * b[k][j] for k in range(3)) + (a[i][3] if j == 3 else 0.0) for j in range(4)]
        for i in range(3)
    ]


def step_errors(est, ref):
    """Mean consecutive-frame translation error (m), and the end point's distance (m)."""
    errs = []
    for i in range(len(est) - 1):
        d = compose(inverse(compose(inverse(ref[i]), ref[i + 1])), compose(inverse(est[i]), est[i + 1]))
        errs.append(math.sqrt(sum(d[k][3] ** 2 for k in range(3))))
    end = math.sqrt(sum((est[-1][k][3] - ref[-1][k][3]) ** 2 for k in range(3)))
    return sum(errs) / max(len(errs), 1), end


def check_mesh(path):
    data = Path(path).read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\nformat binary_little_endian 1.0\n") or end < 0:
        fail(f"{path}: not a binary little-endian PLY")
    header = data[: end + len(b"end_header\n")].decode()
    counts = {}
    for line in header.splitlines():
        if line.startswith("element "):
            _, name, n = line.split()
            counts[name] = int(n)
    v, f = counts.get("vertex", 0), counts.get("face", 0)
    if v < 100 or f < 100:
        fail(f"{path}: only {v} vertices and {f} faces")
    props = [line.split()[-1] for line in header.splitlines() if line.startswith("property float")]
    if props != ["x", "y", "z", "nx", "ny", "nz", "variance"]:
        fail(f"{path}: vertex properties {props}, not x y z nx ny nz variance")
    body = data[len(header):]
    if len(body) != 28 * v + 13 * f:
        fail(f"{path}: {len(body)} bytes of data for {v} vertices and {f} faces")
    for k in range(v):
        x, y, z, nx, ny, nz, var = struct.unpack_from("<7f", body, 28 * k)
        if not all(math.isfinite(c) for c in (x, y, z, nx, ny, nz, var)) or var < 0:
            fail(f"{path}: vertex {k} is not finite or has a negative variance")
        if abs(nx * nx + ny * ny + nz * nz - 1.0) > 1e-3:
            fail(f"{path}: vertex {k} has a normal of length other than 1")
    faces = body[28 * v:]
    for k in range(f):
        n, a, b, c = struct.unpack_from("<B3I", faces, 13 * k)
        if n != 3 or max(a, b, c) >= v:
            fail(f"{path}: face {k} is not a triangle of known vertices")
    return v, f


def check_common(out, frames):
    out = Path(out)
    est = kitti_poses(out / "poses_kitti.txt", frames)
    tum = [line.split() for line in (out / "poses_tum.txt").read_text().splitlines()
           if line.strip() and not line.startswith("#")]
    if len(tum) != frames or any(len(r) != 8 for r in tum):
        fail(f"{out}/poses_tum.txt: {len(tum)} lines of 8 numbers for {frames} frames")
    v, f = check_mesh(out / "mesh.ply")
    report = json.loads((out / "report.json").read_text())
    s = report["summary"]
    if s["frames"] != frames or s["used"] != frames or len(report["frames"]) != frames:
        fail(f"{out}/report.json: summary {s['frames']} frames, {s['used']} used, "
             f"{len(report['frames'])} records, for {frames}")
    if (s["mesh_vertices"], s["mesh_triangles"]) != (v, f):
        fail(f"{out}/report.json: its mesh counts differ from mesh.ply's")
    return est


def main():
    if len(sys.argv) != 4 or sys.argv[1] not in ("demo", "kitti"):
        fail(__doc__)
    mode, out, frames = sys.argv[1], Path(sys.argv[2]), int(sys.argv[3])
    est = check_common(out, frames)
    if mode == "demo":
        png = (out / "topview.png").read_bytes()
        if png[:8] != b"\x89PNG\r\n\x1a\n" or png[12:16] != b"IHDR":
            fail(f"{out}/topview.png: not a PNG")
        w, h = struct.unpack(">II", png[16:24])
        if w < 100 or h < 100:
            fail(f"{out}/topview.png: {w} x {h} pixels")
        ref = kitti_poses(out / "poses_true_kitti.txt", frames)
        mean_step, end = step_errors(est, ref)
        print(f"demo: mean step error {100 * mean_step:.2f} cm (bound {100 * DEMO_MEAN_STEP_M:.2f}),"
              f" end point {end:.3f} m (bound {DEMO_END_M:.3f})")
        if mean_step > DEMO_MEAN_STEP_M or end > DEMO_END_M:
            fail("demo: accuracy out of bounds")
    else:
        e = json.loads((out / "eval.json").read_text())
        print(f"kitti 00: mean step error {100 * e['mean_translation_m']:.2f} cm "
              f"(bound {100 * KITTI00_MEAN_STEP_M:.2f}), {e['mean_rotation_deg']:.4f} deg "
              f"(bound {KITTI00_MEAN_ROT_DEG:.4f})")
        if e["mean_translation_m"] > KITTI00_MEAN_STEP_M or e["mean_rotation_deg"] > KITTI00_MEAN_ROT_DEG:
            fail("kitti 00: accuracy out of bounds")
    print(f"check_outputs: {out} is well formed and within its bounds")


if __name__ == "__main__":
    main()
