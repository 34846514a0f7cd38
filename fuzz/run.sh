#!/usr/bin/env bash
# Runs every fuzz target for the given number of seconds each (default 600), one after the
# other, growing fuzz/corpus/<target>. Needs the nightly toolchain and cargo-fuzz.
# Fails when a target does not build, when cargo fuzz fails, and on a crash, a hang (over
# 10 s on one input) or an allocation over 2 GB, which leave the input in
# fuzz/artifacts/<target>/.
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(kitti_bin pcd ply config_toml core_scan pointcloud2 recording map_file capture velodyne_packet ouster_packet ouster_metadata velodyne_calibration)
# One build for every target (cargo fuzz run would build each on its own).
cargo +nightly fuzz build
log=$(mktemp)
trap 'rm -f "$log"' EXIT
for t in "${targets[@]}"; do
  echo "== $t: ${seconds} s"
  status=0
  cargo +nightly fuzz run "$t" "corpus/$t" -- \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    >"$log" 2>&1 || status=$?
  grep -E "^(#[0-9]+ *DONE|Done [0-9]+ runs|stat::number_of_executed_units|==[0-9]+== ERROR|SUMMARY)" "$log" || true
  if [ "$status" != 0 ]; then
    tail -n 30 "$log"
    echo "$t: cargo fuzz failed (exit $status)"
    exit 1
  fi
  test -z "$(ls "artifacts/$t" 2>/dev/null)" || { echo "$t: failing input in fuzz/artifacts/$t"; exit 1; }
done
