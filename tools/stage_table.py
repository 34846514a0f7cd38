#!/usr/bin/env python3
"""Per-stage time of `slamesh bench` on kitti-mini 00-04, with 1 and 2 threads, for one or
more builds run alternately (docs/journal.md, "Where the second core goes").

    tools/stage_table.py [--rounds N] [--config FILE] [--ceiling] BIN[=CONFIG] [BIN[=CONFIG] ...]

Each round runs every build on every sequence with `--threads 1` and `--threads 2`
(`--repeat 3`, so a warm-up and three timed passes); a stage's figure for a sequence is its
median ms a scan averaged over the rounds, and the table gives the median over the five
sequences, then the 1-thread over 2-thread speed-up by sequence. `BIN=CONFIG` runs that build
with its own configuration file (one build under two presets, or an older build whose preset
names differ); `--config` is for the others. SLAMESH_DATA defaults to ../shared/data.

`--ceiling` also measures, in each round and on each sequence, what this machine's two cores
deliver at that moment: the first build runs `--threads 1` alone, then as two processes at
once, and the ceiling is the sum of the two processes' speeds relative to the one alone (2.0
for two whole cores; less when the cores share a physical core or the host is busy). No
speed-up can exceed it; the table then adds each sequence's speed-up over its ceiling.
"""
import argparse
import json
import os
import statistics
import subprocess

STAGES = ["read", "filter", "bucket", "reconstruct", "associate", "solve", "update", "mesh", "total"]
SEQUENCES = ["00", "01", "02", "03", "04"]


def bench_cmd(binary, seq, threads, config):
    data = os.environ.get("SLAMESH_DATA", "../shared/data")
    cmd = [binary, "bench", f"{data}/kitti-mini/{seq}", "--threads", str(threads), "--repeat", "3", "--json"]
    if config:
        cmd += ["--config", config]
    return cmd


def stages_of(out):
    stages = json.loads(out.strip().splitlines()[-1])["stages"]
    return {s: stages[s]["median_ms"] for s in STAGES if s in stages}


def bench(binary, seq, threads, config):
    out = subprocess.run(bench_cmd(binary, seq, threads, config), check=True, capture_output=True, text=True)
    return stages_of(out.stdout)


def ceiling(binary, seq, config):
    """The two cores' speed on this sequence relative to one core's, measured now: one
    single-thread run alone, then two at once."""
    alone = bench(binary, seq, 1, config)["total"]
    cmd = bench_cmd(binary, seq, 1, config)
    pair = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True) for _ in range(2)]
    outs = [p.communicate()[0] for p in pair]
    if any(p.returncode != 0 for p in pair):
        raise SystemExit(f"{binary} bench failed on {seq}")
    return sum(alone / stages_of(out)["total"] for out in outs)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--config")
    ap.add_argument("--ceiling", action="store_true")
    ap.add_argument("binaries", nargs="+", metavar="BIN[=CONFIG]")
    args = ap.parse_args()
    # Each build as given, its binary, and its configuration: its own after `=`, else --config.
    builds = [(b, *(b.split("=", 1) if "=" in b else (b, args.config))) for b in args.binaries]
    # runs[build][threads][seq] = list of per-round stage dicts
    runs = {b: {t: {s: [] for s in SEQUENCES} for t in (1, 2)} for b, _, _ in builds}
    ceilings = {s: [] for s in SEQUENCES}
    for _ in range(args.rounds):
        for seq in SEQUENCES:
            if args.ceiling:
                _, binary, config = builds[0]
                ceilings[seq].append(ceiling(binary, seq, config))
            for threads in (1, 2):
                for b, binary, config in builds:
                    runs[b][threads][seq].append(bench(binary, seq, threads, config))
    for b, _, _ in builds:
        print(f"\n{b}\n")
        print("| stage | 1 thread | 2 threads | speed-up | by sequence " + " / ".join(SEQUENCES) + " |")
        print("|---|---|---|---|---|")
        # mean[stage][threads][seq]: the stage's median averaged over the rounds.
        mean = {
            stage: {t: {s: statistics.mean(r[stage] for r in runs[b][t][s]) for s in SEQUENCES} for t in (1, 2)}
            for stage in STAGES
        }
        for stage in STAGES:
            m = mean[stage]
            med = {t: statistics.median(m[t].values()) for t in (1, 2)}
            by_seq = " / ".join(f"{m[1][s] / m[2][s]:.2f}" if m[2][s] > 0 else "-" for s in SEQUENCES)
            up = med[1] / med[2] if med[2] > 0 else float("nan")
            print(f"| {stage} | {med[1]:.2f} | {med[2]:.2f} | {up:.2f} | {by_seq} |")
        for t in (1, 2):
            totals = " / ".join(f"{mean['total'][t][s]:.1f}" for s in SEQUENCES)
            print(f"\ntotals by sequence, {t} thread(s): {totals} ms")
        if args.ceiling:
            ceil = {s: statistics.mean(ceilings[s]) for s in SEQUENCES}
            over = " / ".join(f"{mean['total'][1][s] / mean['total'][2][s] / ceil[s]:.2f}" for s in SEQUENCES)
            print("\ntwo cores' ceiling by sequence: " + " / ".join(f"{ceil[s]:.2f}" for s in SEQUENCES))
            print("speed-up over ceiling by sequence: " + over)


if __name__ == "__main__":
    main()
