#!/usr/bin/env bash
# Resident memory under memory caps (docs/journal.md, "The memory cap" and "Memory with
# 64-beam scans"): for each cap in MB given ("none" for no cap), runs slamesh and prints the
# class, the layer budget, the RSS at frames 1, 101, ..., 901 and the last, the peak, and the
# accuracy. Without INPUT: `slamesh demo --frames 1000` (the town, its consecutive error).
# With INPUT=DIR (a KITTI-style sequence with poses.txt, e.g. one written by
# `cargo run --release --example write_drive -- --out DIR --azimuth-steps 2000`): `slamesh run
# DIR --save-evicted` and the segment errors from `slamesh eval`.
# Usage: [INPUT=DIR] tools/memory_caps.sh none 40 48 64 (after cargo build --release).
set -euo pipefail
bin=${SLAMESH_BIN:-target/release/slamesh}
for cap in "$@"; do
  out=$(mktemp -d)
  flags=()
  [ "$cap" != none ] && flags=(--memory-cap "$cap")
  if [ -n "${INPUT:-}" ]; then
    [ "$cap" != none ] && flags+=(--save-evicted)
    cmd=("$bin" run "$INPUT" --out "$out" "${flags[@]}" -q)
  else
    cmd=("$bin" demo --frames 1000 --out "$out" "${flags[@]}" -q)
  fi
  "${cmd[@]}" > "$out.log" 2>&1 || {
    echo "cap $cap MB: $(grep -m1 error "$out.log")"; rm -rf "$out" "$out.log"; continue; }
  if [ -n "${INPUT:-}" ]; then
    "$bin" eval --estimate "$out/poses_kitti.txt" --reference "$INPUT/poses.txt" \
      | grep -E "ATE|00 m segments" | tr -s ' ' | paste -sd ';' >> "$out.log"
  fi
  python3 - "$cap" "$out/report.json" "$out.log" <<'PY'
import json, sys
cap, path, log = sys.argv[1], sys.argv[2], sys.argv[3]
r = json.load(open(path))
f, s = r["frames"], r["summary"]
rss = [f[k]["rss_mb"] for k in range(0, len(f), 100)] + [f[-1]["rss_mb"]]
lines = [l.strip() for l in open(log)]
acc = next((l for l in lines if "consecutive error" in l), None)
if acc is None:
    import re
    evals = next((l for l in lines if "ATE" in l), "")
    ate = re.search(r"ATE[^:]*:\s*([0-9.]+ m)", evals)
    seg = [float(x) for x in re.findall(r"([0-9.]+) % translation", evals)]
    acc = (f"ATE {ate.group(1)}, worst 100-800 m segment {max(seg):.3f} %"
           if ate and seg else "no accuracy line")
print(f"cap {cap} MB: class {s['capacity']}, budget {s['max_layers']} layers, "
      f"RSS {', '.join(f'{x:.1f}' for x in rss)} MB, peak {s['peak_rss_mb']:.1f} MB, "
      f"{s['seconds']:.1f} s; {acc}")
PY
  rm -rf "$out" "$out.log"
done
