#!/usr/bin/env python3
"""What loop closure costs a run that has no loop to close, and whether it changes its bytes.

Runs `slamesh run INPUT` with `--loop-closure off` and `on` in alternating rounds (off, on,
on, off, off, on, ...: both see the machine in the same state, and each goes first as often),
then prints, for each, the median over
the rounds of the run's wall time, of its median frame, of its peak memory and of the CPU
time it took (user and system, all threads), the ratios
on/off, and whether every round wrote the same poses and mesh as the first "off" round.

    tools/loop_closure_cost.py BIN INPUT [--rounds 5] [--out DIR] [-- EXTRA RUN FLAGS]

Exits 1 when a round's poses or mesh differ from the first "off" round's, or when a round
closed a loop (the input has one, so it measures something else).
"""
import argparse
import filecmp
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

COMPARED = ("poses_kitti.txt", "poses_tum.txt", "mesh.ply")


def one_run(binary, source, out, mode, extra):
    start, cpu0 = time.monotonic(), resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(
        [binary, "run", source, "--out", str(out), "--loop-closure", mode, "-q", "--no-picture",
         *extra],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    wall = time.monotonic() - start
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime
    summary = json.loads((out / "report.json").read_text())["summary"]
    median_frame = dict(summary["stage_ms"])["total"]["median"]
    closures = len((summary.get("loop_closure") or {}).get("closures", []))
    return wall, median_frame, summary["peak_rss_mb"], cpu, closures


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("binary")
    ap.add_argument("input")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default="target/loop-closure-cost")
    ap.add_argument("extra", nargs="*", help="more flags for `slamesh run` (after --)")
    a = ap.parse_args()
    out = Path(a.out)
    got = {"off": [], "on": []}
    same = True
    for r in range(a.rounds):
        for mode in ("off", "on") if r % 2 == 0 else ("on", "off"):
            run_out = out / f"{mode}-{r}"
            got[mode].append(one_run(a.binary, a.input, run_out, mode, a.extra))
            first = out / "off-0"
            if not first.exists():
                continue
            for f in COMPARED:
                if not filecmp.cmp(first / f, run_out / f, shallow=False):
                    print(f"round {r} {mode}: {f} differs from round 0 off's", file=sys.stderr)
                    same = False
    med = {m: [statistics.median(x[i] for x in got[m]) for i in range(4)] for m in got}
    closed = sum(x[4] for x in got["on"])
    for m in ("off", "on"):
        w, f, rss, cpu = med[m]
        print(f"{m:>3}: run {w:.2f} s, median frame {f:.2f} ms, peak memory {rss:.0f} MB, "
              f"CPU {cpu:.2f} s (medians of {a.rounds} rounds)")
    ratio = [med["on"][i] / med["off"][i] for i in range(4)]
    print(f"on/off: run {ratio[0]:.3f}, median frame {ratio[1]:.3f}, peak memory "
          f"{ratio[2]:.3f}, CPU {ratio[3]:.3f}")
    print("poses and mesh: " + ("the same bytes in every round" if same else "DIFFER"))
    if closed:
        print(f"{closed} loops closed: this input has a loop", file=sys.stderr)
    return 0 if same and not closed else 1


if __name__ == "__main__":
    sys.exit(main())
