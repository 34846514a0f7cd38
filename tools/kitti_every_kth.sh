#!/usr/bin/env bash
# kitti-mini with only every k-th scan kept (a lower scan rate: larger motion between scans):
# makes each thinned sequence (links to the scans, the matching lines of poses.txt, calib.txt),
# runs `slamesh run --preset kitti` on it and evaluates against it.
#
#   tools/kitti_every_kth.sh [K ...]     # default 1 2 3; SLAMESH_DATA defaults to ../shared/data
set -euo pipefail
cd "$(dirname "$0")/.."
data=$(realpath "${SLAMESH_DATA:-../shared/data}")
cargo build --release --bin slamesh -q
bin=$PWD/target/release/slamesh
work=$PWD/target/every-kth
ks=("$@"); [ ${#ks[@]} -gt 0 ] || ks=(1 2 3)
for k in "${ks[@]}"; do
  for s in 00 01 02 03 04; do
    d=$work/$s-k$k
    rm -rf "$d"; mkdir -p "$d/velodyne"
    src=$data/kitti-mini/$s
    cp "$src/calib.txt" "$d/"
    i=0
    for f in $(ls "$src"/velodyne/*.bin | sort | awk -v k="$k" 'NR % k == 1 || k == 1'); do
      ln -s "$f" "$d/velodyne/$(printf %06d $i).bin"; i=$((i + 1))
    done
    awk -v k="$k" 'NR % k == 1 || k == 1' "$src/poses.txt" > "$d/poses.txt"
    "$bin" run "$d" --out "$d/out" --preset kitti -q --no-picture > /dev/null
    "$bin" eval --estimate "$d/out/poses_kitti.txt" --reference "$d" --json > "$d/eval.json"
    python3 - "$d" "$k" "$s" <<'PY'
import json, sys
d, k, s = sys.argv[1:]
e = json.load(open(f"{d}/eval.json"))
h = json.load(open(f"{d}/out/report.json"))["summary"]["health"]["counts"]
print(f"every {k}: {s}: {e['pairs']} steps, mean {100 * e['mean_translation_m']:.2f} cm, "
      f"worst {100 * e['max_translation_m']:.2f} cm, {e['mean_rotation_deg']:.4f} deg; {h}")
PY
  done
done
