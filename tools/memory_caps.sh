#!/usr/bin/env bash
# Resident memory over a 1 000-frame town drive under memory caps (docs/benchmarks.md, "The
# memory cap"): for each cap in MB given, runs `slamesh demo --frames 1000 --memory-cap CAP`
# and prints the class, the layer budget, the RSS at frames 1, 101, ..., 901 and 1 000, the
# peak and the demo's consecutive error. Usage: tools/memory_caps.sh 41 48 64 (after cargo build --release).
set -euo pipefail
bin=${SLAMESH_BIN:-target/release/slamesh}
for cap in "$@"; do
  out=$(mktemp -d)
  "$bin" demo --frames 1000 --out "$out" --memory-cap "$cap" -q > "$out.log" 2>&1 || {
    echo "cap $cap MB: $(grep -m1 error "$out.log")"; rm -rf "$out" "$out.log"; continue; }
  python3 - "$cap" "$out/report.json" "$out.log" <<'PY'
import json, sys
cap, path, log = sys.argv[1], sys.argv[2], sys.argv[3]
r = json.load(open(path))
f, s = r["frames"], r["summary"]
rss = [f[k]["rss_mb"] for k in range(0, len(f), 100)] + [f[-1]["rss_mb"]]
print(f"cap {cap} MB: class {s['capacity']}, budget {s['max_layers']} layers, "
      f"RSS {', '.join(f'{x:.1f}' for x in rss)} MB, peak {s['peak_rss_mb']:.0f} MB; "
      + next((l.strip() for l in open(log) if "consecutive error" in l), "no accuracy line"))
PY
  rm -rf "$out" "$out.log"
done
