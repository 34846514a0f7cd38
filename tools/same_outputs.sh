#!/usr/bin/env bash
# Checks that a change leaves slamesh's outputs unchanged, byte for byte: builds BASE (a git
# revision, default HEAD) in a worktree and the working tree as it is, runs both on
# - kitti-mini 00-04 (preset kitti, 1 and 2 threads);
# - the simulated demo (60 frames);
# - every committed input kind: ROS 1 bags, MCAP files, ROS 2 bag folders (db3 and MCAP), a
#   folder of scans, one PCD file, Velodyne and Ouster captures (an HDL-64E with its
#   calibration);
# - each way the pose can be known: `mesh` at given poses, `run --save-map` then `localize` in
#   that map (the search for the first pose), and a sliding window;
# - the run's stages: the IMU (a simulated shaken car with its readings), the navigation map
#   (with the floor file beside a saved map) and clearing what moves;
# and compares the trajectories and meshes they write. Timings (report.json) are not compared.
#
#   tools/same_outputs.sh [BASE]        # SLAMESH_DATA defaults to ../shared/data
#   BASE_BIN=a NEW_BIN=b tools/same_outputs.sh   # two binaries built already (any profile)
set -euo pipefail
cd "$(dirname "$0")/.."
data=${SLAMESH_DATA:-../shared/data}
work=target/same-outputs
rm -rf "$work/runs"
mkdir -p "$work/runs"
if [ -z "${BASE_BIN:-}" ]; then
  # Resolved here: inside the worktree, HEAD would name the worktree's own commit.
  base=$(git rev-parse --verify "${1:-HEAD}^{commit}")
  if [ ! -d "$work/base" ]; then
    git worktree add --detach "$work/base" "$base" >/dev/null
  else
    git -C "$work/base" checkout --detach -q "$base"
  fi
  (cd "$work/base" && cargo build --release --bin slamesh -q --target-dir ../base-target)
  cargo build --release --bin slamesh -q
  BASE_BIN="$work/base-target/release/slamesh"
  NEW_BIN=target/release/slamesh
  label=$(git rev-parse --short "$base")
else
  label=$BASE_BIN
fi
declare -A bin=([base]="$BASE_BIN" [new]="$NEW_BIN")
# A shaken car with its IMU at 200 Hz (the IMU's deskew and prior), written once by this tree.
cargo build --release --example write_drive -q
target/release/examples/write_drive --out "$work/shaken" --shaken --imu 200 --frames 80 >/dev/null
fx=tests/fixtures
k=$data/kitti-mini
for side in base new; do
  b=${bin[$side]}
  o=$work/runs/$side
  for s in 00 01 02 03 04; do
    for t in 1 2; do
      "$b" run "$k/$s" --out "$o/k$s-t$t" --preset kitti --threads "$t" -q
    done
  done
  "$b" demo --frames 60 --out "$o/demo" -q >/dev/null
  for rec in bag/bz2.bag bag/lz4.bag bag/none.bag mcap/cdr-zstd.mcap mcap/cdr-lz4.mcap \
    mcap/cdr-none.mcap mcap/ros1-lz4.mcap ros2-db3 ros2-mcap scans; do
    "$b" run "$fx/recordings/$rec" --out "$o/rec-${rec//\//-}" --threads 2 -q --no-picture
  done
  "$b" run "$fx/pcd/ascii_extra_fields.pcd" --out "$o/pcd-one" --threads 1 -q --no-picture || true
  # (hdl32e-street and ouster-os2-128-rng19 hold less than a turn: the readers' tests use them.)
  for cap in velodyne-models.pcap hdl32e-drive.pcap \
    ouster-os0-32-dual.pcap ouster-os1-32-legacy.pcap ouster-os1-128-lowdata.pcap; do
    "$b" run "$fx/packets/$cap" --out "$o/cap-$cap" --threads 2 -q --no-picture
  done
  "$b" run "$fx/packets/hdl64e-s2-street.pcap" --sensor hdl64e-s2 \
    --calibration "$fx/packets/hdl64e-s2.1-sztaki.yml" --out "$o/cap-hdl64e" --threads 2 -q --no-picture
  "$b" mesh "$k/00" --poses "$k/00/poses.txt" --calib "$k/00/calib.txt" --out "$o/mesh00" \
    --threads 2 -q --no-picture
  "$b" run "$k/00" --out "$o/save00" --preset kitti --threads 2 -q --no-picture \
    --save-map "$o/save00/map.slamesh"
  "$b" localize "$k/00" --map "$o/save00/map.slamesh" --out "$o/loc00" --threads 2 -q --no-picture
  "$b" run "$k/01" --out "$o/window01" --preset kitti --threads 2 -q --no-picture \
    --evict-after 3
  # The run's stages: the navigation map (its files, the scans' floor beside the saved map, its
  # layers on the mesh's vertices) and clearing what moves.
  "$b" run "$k/02" --out "$o/navmap02" --preset kitti --threads 2 -q --no-picture --navmap \
    --save-map "$o/navmap02/map.slamesh"
  "$b" run "$k/03" --out "$o/dynamic03" --preset kitti --threads 2 -q --no-picture --dynamic on
  "$b" run "$work/shaken" --out "$o/shaken-imu" --threads 2 -q --no-picture
done
differ=0
compared=0
for f in $(cd "$work/runs/base" && find . -name 'poses_*.txt' -o -name 'mesh.ply' -o -name '*.slamesh' \
  -o -name '*.floor' -o -name 'map.pgm' -o -name 'map.yaml' -o -name '*.asc' -o -name 'navmesh.ply' | sort); do
  compared=$((compared + 1))
  cmp -s "$work/runs/base/$f" "$work/runs/new/$f" || { echo "differs: $f"; differ=$((differ + 1)); }
done
echo "$compared files compared against $label, $differ differ"
[ "$differ" = 0 ]
