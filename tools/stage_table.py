#!/usr/bin/env python3
"""Per-stage time of `slamesh bench` on kitti-mini 00-04, with 1 and 2 threads, for one or
more builds run alternately (docs/benchmarks.md, "Where the second core goes").

    tools/stage_table.py [--rounds N] [--config FILE] BIN[=CONFIG] [BIN[=CONFIG] ...]

Each round runs every build on every sequence with `--threads 1` and `--threads 2`
(`--repeat 3`, so a warm-up and three timed passes); a stage's figure for a sequence is its
median ms a scan averaged over the rounds, and the table gives the median over the five
sequences, then the 1-thread over 2-thread speed-up by sequence. `BIN=CONFIG` runs that build
with its own configuration file (one build under two presets, or an older build whose preset
names differ); `--config` is for the others. SLAMESH_DATA defaults to ../shared/data.
"""
import argparse
import json
import os
import statistics
import subprocess

STAGES = ["read", "filter", "bucket", "reconstruct", "associate", "solve", "update", "mesh", "total"]
SEQUENCES = ["00", "01", "02", "03", "04"]


def bench(binary, seq, threads, config):
    data = os.environ.get("SLAMESH_DATA", "../shared/data")
    cmd = [binary, "bench", f"{data}/kitti-mini/{seq}", "--threads", str(threads), "--repeat", "3", "--json"]
    if config:
        cmd += ["--config", config]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    stages = json.loads(out.strip().splitlines()[-1])["stages"]
    return {s: stages[s]["median_ms"] for s in STAGES if s in stages}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--config")
    ap.add_argument("binaries", nargs="+", metavar="BIN[=CONFIG]")
    args = ap.parse_args()
    # Each build with its configuration: its own after `=`, else --config.
    config_of = {b: (b.split("=", 1)[1] if "=" in b else args.config) for b in args.binaries}
    # runs[binary][threads][seq] = list of per-round stage dicts
    runs = {b: {t: {s: [] for s in SEQUENCES} for t in (1, 2)} for b in args.binaries}
    for _ in range(args.rounds):
        for seq in SEQUENCES:
            for threads in (1, 2):
                for b in args.binaries:
                    binary = b.split("=", 1)[0]
                    runs[b][threads][seq].append(bench(binary, seq, threads, config_of[b]))
    for b in args.binaries:
        print(f"\n{b}\n")
        print("| stage | 1 thread | 2 threads | speed-up | by sequence " + " / ".join(SEQUENCES) + " |")
        print("|---|---|---|---|---|")
        for stage in STAGES:
            mean = {t: {s: statistics.mean(r[stage] for r in runs[b][t][s]) for s in SEQUENCES} for t in (1, 2)}
            med = {t: statistics.median(mean[t].values()) for t in (1, 2)}
            by_seq = " / ".join(
                f"{mean[1][s] / mean[2][s]:.2f}" if mean[2][s] > 0 else "-" for s in SEQUENCES
            )
            up = med[1] / med[2] if med[2] > 0 else float("nan")
            print(f"| {stage} | {med[1]:.2f} | {med[2]:.2f} | {up:.2f} | {by_seq} |")
        for t in (1, 2):
            totals = " / ".join(
                f"{statistics.mean(r['total'] for r in runs[b][t][s]):.1f}" for s in SEQUENCES
            )
            print(f"\ntotals by sequence, {t} thread(s): {totals} ms")


if __name__ == "__main__":
    main()
