#!/usr/bin/env bash
# Runs every fuzz target for the given number of seconds each (default 600), growing
# fuzz/corpus/<target>. Needs the nightly toolchain and cargo-fuzz.
#   fuzz/run.sh [SECONDS [TARGET...]]
# Environment: FUZZ_JOBS targets at a time (default: the cores present); FUZZ_SANITIZER
# (default address; CI's smoke pass uses none: the code fuzzed forbids unsafe code, and the
# build is faster).
# Fails when a target does not build, when the fuzzer fails, and on a crash, a hang (over
# 10 s on one input) or an allocation over 2 GB, which leave the input in
# fuzz/artifacts/<target>/.
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-600}
shift || true
targets=("$@")
# By default every target Cargo.toml names (a new one is fuzzed the day it lands).
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(awk '/^\[\[bin\]\]/ { bin = 1 } bin && /^name = / { gsub(/"/, "", $3); print $3; bin = 0 }' Cargo.toml)
jobs=${FUZZ_JOBS:-$(nproc)}
sanitizer=${FUZZ_SANITIZER:-address}
# One build for every target; each binary is then run as `cargo fuzz run` would run it.
cargo +nightly fuzz build --sanitizer "$sanitizer"
triple=$(rustc +nightly -vV | sed -n 's/^host: //p')
logs=$(mktemp -d)
trap 'rm -rf "$logs"' EXIT

fuzz_one() {
  local t=$1 status=0
  mkdir -p "artifacts/$t" "corpus/$t"
  "target/$triple/release/$t" -artifact_prefix="artifacts/$t/" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    "corpus/$t" >"$logs/$t" 2>&1 || status=$?
  # The target's report in one write, so that reports of parallel targets do not interleave.
  {
    echo "== $t: ${seconds} s"
    grep -E "^(#[0-9]+ *DONE|Done [0-9]+ runs|stat::number_of_executed_units|==[0-9]+== ERROR|SUMMARY)" "$logs/$t" || true
    if [ "$status" != 0 ]; then
      tail -n 30 "$logs/$t"
      echo "$t: the fuzzer failed (exit $status)"
    elif [ -n "$(ls "artifacts/$t")" ]; then
      echo "$t: failing input in fuzz/artifacts/$t"
      status=1
    fi
  } >"$logs/$t.report"
  cat "$logs/$t.report"
  [ "$status" = 0 ]
}

failed=0
running=0
for t in "${targets[@]}"; do
  fuzz_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then
    wait -n || failed=1
    running=$((running - 1))
  fi
done
while [ "$running" -gt 0 ]; do
  wait -n || failed=1
  running=$((running - 1))
done
exit "$failed"
