#!/usr/bin/env bash
# Checks that a change leaves slamesh's outputs unchanged, byte for byte: builds BASE (a git
# revision, default HEAD) in a worktree and the working tree as it is, runs both on kitti-mini
# 00-04 (preset kitti, 1 and 2 threads) and on the simulated demo (60 frames), and compares
# the trajectories and meshes they write. Timings (report.json) are not compared.
#
#   tools/same_outputs.sh [BASE]        # SLAMESH_DATA defaults to ../shared/data
set -euo pipefail
cd "$(dirname "$0")/.."
# Resolved here: inside the worktree, HEAD would name the worktree's own commit.
base=$(git rev-parse --verify "${1:-HEAD}^{commit}")
data=${SLAMESH_DATA:-../shared/data}
work=target/same-outputs
rm -rf "$work/runs"
mkdir -p "$work/runs"
if [ ! -d "$work/base" ]; then
  git worktree add --detach "$work/base" "$base" >/dev/null
else
  git -C "$work/base" checkout --detach -q "$base"
fi
(cd "$work/base" && cargo build --release --bin slamesh -q --target-dir ../base-target)
cargo build --release --bin slamesh -q
declare -A bin=([base]="$work/base-target/release/slamesh" [new]=target/release/slamesh)
for side in base new; do
  for s in 00 01 02 03 04; do
    for t in 1 2; do
      "${bin[$side]}" run "$data/kitti-mini/$s" --out "$work/runs/$side/k$s-t$t" --preset kitti --threads "$t" -q
    done
  done
  "${bin[$side]}" demo --frames 60 --out "$work/runs/$side/demo" -q >/dev/null
done
differ=0
compared=0
for f in $(cd "$work/runs/base" && find . -name 'poses_*.txt' -o -name 'mesh.ply' | sort); do
  compared=$((compared + 1))
  cmp -s "$work/runs/base/$f" "$work/runs/new/$f" || { echo "differs: $f"; differ=$((differ + 1)); }
done
echo "$compared files compared against $(git rev-parse --short "$base"), $differ differ"
[ "$differ" = 0 ]
