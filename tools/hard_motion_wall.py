#!/usr/bin/env python3
"""Whole-run wall time of `slamesh run` on the carried hard-motion drives (hand-held and
drone, seeds 1-3, 120 frames) for two builds run alternately, with each run's ATE
(docs/journal.md, "The turn from the scans' azimuth profiles").

    tools/hard_motion_wall.py [--rounds N] [--drives DIR] OLD_BIN NEW_BIN

The drives are written first if DIR (default /tmp) lacks them, by this checkout's
`write_drive` example (`hm-DRIVE-SEED`). Each round runs every drive with each build in turn
(`run DIR --out OUT --no-picture --threads 2`, timed around the process: start, reading and
writing included), then `NEW_BIN eval` for the ATE. Prints the median of the rounds for each
drive, the ratio NEW / OLD, and the median and total ratios.
"""
import argparse
import os
import re
import statistics
import subprocess
import time

DRIVES = [(d, s) for d in ("hand-held", "drone") for s in (1, 2, 3)]


def ate(binary, out, reference):
    text = subprocess.run(
        [binary, "eval", "--estimate", f"{out}/poses_kitti.txt", "--reference", reference],
        check=True, capture_output=True, text=True).stdout
    return float(re.search(r"ATE \(rigidly aligned\):\s+([0-9.]+) m", text).group(1))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--drives", default="/tmp")
    ap.add_argument("old")
    ap.add_argument("new")
    a = ap.parse_args()
    for d, s in DRIVES:
        path = f"{a.drives}/hm-{d}-{s}"
        if not os.path.isdir(path):
            subprocess.run(["cargo", "run", "--release", "-q", "--example", "write_drive", "--",
                            "--out", path, "--frames", "120", "--path", d, "--seed", str(s)],
                           check=True, stdout=subprocess.DEVNULL)
    times = {(b, d, s): [] for b in ("old", "new") for d, s in DRIVES}
    ates = {}
    for _ in range(a.rounds):
        for d, s in DRIVES:
            for b in ("old", "new"):
                binary = getattr(a, b)
                out = f"{a.drives}/hm-out-{b}-{d}-{s}"
                start = time.monotonic()
                subprocess.run([binary, "run", f"{a.drives}/hm-{d}-{s}", "--out", out,
                                "--no-picture", "--threads", "2"],
                               check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                times[(b, d, s)].append(time.monotonic() - start)
                ates[(b, d, s)] = ate(a.new, out, f"{a.drives}/hm-{d}-{s}")
    ratios = []
    total = {"old": 0.0, "new": 0.0}
    print("| drive | old | new | ratio | ATE old -> new |\n|---|---|---|---|---|")
    for d, s in DRIVES:
        m = {b: statistics.median(times[(b, d, s)]) for b in ("old", "new")}
        for b in m:
            total[b] += m[b]
        ratios.append(m["new"] / m["old"])
        print(f"| {d} {s} | {m['old']:.2f} s | {m['new']:.2f} s | {ratios[-1]:.3f} | "
              f"{ates[('old', d, s)]:.3f} -> {ates[('new', d, s)]:.3f} m |")
    print(f"median ratio {statistics.median(ratios):.3f}, total ratio {total['new'] / total['old']:.3f}")


if __name__ == "__main__":
    main()
