#!/usr/bin/env bash
# Runs every fuzz target for the given number of seconds each (default 600), growing
# fuzz/corpus/<target>. Needs the nightly toolchain only: the targets are built here with the
# flags `cargo fuzz build` passes (so cargo-fuzz need not be installed; `cargo +nightly fuzz
# run TARGET` works on this crate as well).
#   fuzz/run.sh [SECONDS [TARGET...]]
# Environment: FUZZ_JOBS targets at a time (default: the cores present); FUZZ_SANITIZER
# (address, the default, or none: the code fuzzed forbids unsafe code, and the build is
# faster); FUZZ_QUICK_BUILD=1 for a smoke pass (CI's): the crates fuzzed unoptimised and
# without debug information, built in half the time, fuzzing more slowly.
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
triple=$(rustc +nightly -vV | sed -n 's/^host: //p')
# One build for every target, as cargo-fuzz 0.13 builds them: libFuzzer's coverage
# instrumentation and `cfg(fuzzing)` in RUSTFLAGS, with `--target` named so that build scripts
# and procedural macros are left uninstrumented; each binary is then run as `cargo fuzz run`
# would run it.
flags=(-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4
  -Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table
  -Cllvm-args=-sanitizer-coverage-trace-compares -Cllvm-args=-simplifycfg-branch-fold-threshold=0
  --cfg fuzzing)
case "$triple" in *-linux-*) flags+=(-Cllvm-args=-sanitizer-coverage-stack-depth) ;; esac
case "$sanitizer" in
  none) ;;
  *) flags+=("-Zsanitizer=$sanitizer") ;;
esac
profile=(--config 'profile.release.debug="line-tables-only"')
if [ "${FUZZ_QUICK_BUILD:-0}" = 1 ]; then
  # Every crate but the targets' own unoptimised: the pipeline's generic code is compiled
  # in the targets, and unoptimised there it took 27 s to read core_scan's corpus, not 7.
  profile=(--config 'profile.release.package."*".opt-level=0' --config profile.release.debug=0)
else
  # cargo-fuzz's reason: with the coverage passes, more than one codegen unit leaves ThinLTO
  # nothing to inline across units, and the fuzzer runs markedly slower.
  flags+=(-Ccodegen-units=1)
fi
RUSTFLAGS="${flags[*]} ${RUSTFLAGS:-}" cargo +nightly build --release --target "$triple" --bins "${profile[@]}"
# As `cargo fuzz run` sets it: the instrumented standard library and crates can define a
# global twice, which ASan would report as a violation of the one-definition rule.
[ "$sanitizer" != address ] || export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_odr_violation=0"
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
