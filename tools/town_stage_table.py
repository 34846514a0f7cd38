#!/usr/bin/env python3
"""The table of docs/journal.md's "All the cores" from tools/device_scaling.sh's reports:
for each build and thread count, each stage's median ms a frame (the median over the rounds of
each run's `summary.stage_ms` median), the speed against one thread and the loop's seconds.

    tools/town_stage_table.py DIR      # DIR holds reports/town-BUILD-tN-rK.json
"""

import glob
import json
import statistics
import sys

STAGES = ["filter", "bucket", "reconstruct", "associate", "solve", "update", "mesh", "total"]


def main(folder):
    rows = {}
    for path in sorted(glob.glob(f"{folder}/reports/*.json")):
        _, build, threads, _ = path.rsplit("/", 1)[1][:-5].split("-")
        summary = json.load(open(path))["summary"]
        medians = {name: spread["median"] for name, spread in summary["stage_ms"]}
        rows.setdefault((build, int(threads[1:])), []).append((medians, summary["seconds"]))
    print("build threads " + " ".join(f"{s[:11]:>11}" for s in STAGES) + "   speed  loop_s")
    one = {}
    for (build, threads), runs in sorted(rows.items()):
        med = {s: statistics.median(r[0][s] for r in runs) for s in STAGES}
        one.setdefault(build, med["total"])
        cells = " ".join(f"{med[s]:11.2f}" for s in STAGES)
        loop = statistics.median(r[1] for r in runs)
        print(f"{build:5} {threads:7} {cells}  {one[build] / med['total']:5.2f}x  {loop:6.1f}")


if __name__ == "__main__":
    main(sys.argv[1])
