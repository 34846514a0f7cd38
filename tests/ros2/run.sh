#!/usr/bin/env bash
# Runs tests/ros2/check_node.py (a stock rclpy peer against `slamesh ros2`) inside a network
# namespace of its own that has only loopback, so that no DDS packet leaves the machine.
# Needs root (unshare -n) and a Python with rclpy. WRITE_DRIVE, the example `write_drive`'s
# binary, writes the IMU check's shaken drive (60 frames, a 200 Hz IMU) first.
#   tests/ros2/run.sh SLAMESH_BIN PYTHON DATA_DIR WORK_DIR WRITE_DRIVE
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
[ $# -eq 5 ] || { echo "usage: $0 SLAMESH_BIN PYTHON DATA_DIR WORK_DIR WRITE_DRIVE" >&2; exit 2; }
bin=$(realpath "$1"); py=$2; data=$(realpath "$3"); work=$4
rm -rf "$work"; mkdir -p "$work"; work=$(realpath "$work")
"$5" --out "$work/shaken" --path car --shaken --imu 200 --frames 60 >/dev/null
exec unshare -n bash -c '
  set -euo pipefail
  ip link set lo up
  ip link set lo multicast on
  ip route add 224.0.0.0/4 dev lo
  # Nothing but loopback here: say so, and stop if a route leads anywhere else.
  if ip route | grep -v "dev lo" | grep -q .; then echo "a route leaves loopback" >&2; exit 1; fi
  export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
  exec "$0" "$1/check_node.py" --slamesh "$2" --python "$0" --data "$3" --work "$4" \
    --drive "$4/shaken"
' "$py" "$here" "$bin" "$data" "$work"
