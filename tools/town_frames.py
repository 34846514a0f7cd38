#!/usr/bin/env python3
"""The pipeline's time on the simulated town for one or more builds run alternately
(docs/journal.md, "Issue 39's steady state against 5be1322").

    tools/town_frames.py [--rounds N] [--frames F] BIN[=CONFIG] [BIN[=CONFIG] ...]

Each round runs `BIN demo --frames F --out OUT -q` (the preset `town`, or `--config CONFIG`)
for every build in turn. The demo's frame loop waits on the simulator (about 88 ms a scan
here), so its wall time says little of the pipeline; the figure is the sum over frames of
`frames[].ms.total` in `report.json`, with the median frame. Prints each run, then each
build's median of the rounds and its ratio to the first build's. Accuracy is not computed
here: `slamesh eval` on OUT's `poses_kitti.txt` against `poses_true_kitti.txt` gives it.
"""
import argparse
import json
import statistics
import subprocess


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--out", default="/tmp/town-frames")
    ap.add_argument("builds", nargs="+")
    a = ap.parse_args()
    sums = {b: [] for b in a.builds}
    for r in range(a.rounds):
        for k, b in enumerate(a.builds):
            binary, _, config = b.partition("=")
            out = f"{a.out}-{k}-{r}"
            cmd = [binary, "demo", "--frames", str(a.frames), "--out", out, "-q"]
            if config:
                cmd += ["--config", config]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            with open(f"{out}/report.json") as f:
                frames = json.load(f)["frames"]
            ms = [fr["ms"]["total"] for fr in frames if fr.get("ms")]
            sums[b].append(sum(ms) / 1000)
            print(f"round {r} {b}: {sums[b][-1]:.1f} s, median {statistics.median(ms):.2f} ms a frame ({out})",
                  flush=True)
    first = statistics.median(sums[a.builds[0]])
    for b in a.builds:
        m = statistics.median(sums[b])
        print(f"{b}: median {m:.1f} s, ratio {m / first:.3f}")


if __name__ == "__main__":
    main()
