#!/usr/bin/env bash
# cargo-mutants over the lines a change touched, for a developer before stopping (issue 87):
# every mutant cargo-mutants makes on a changed line of core/ or std-adapters/, each tested by
# the package's tests; what survives is printed (and kept in target/mutants-touched/).
#
#   tools/mutants_touched.sh [BASE] [--full]
#
# BASE: the revision the change starts from (default: HEAD~1, the last commit alone).
# core/'s mutants run core's own tests (a mutant builds and tests in about 8 s here). std's
# run the slamesh crate's unit tests (`--lib`, about a minute a mutant, the crate's rebuild);
# `--full` runs its integration tests too (SLAMESH_DATA set; several minutes a mutant), which
# is what CI's tests are. A survivor is a line no test watches: kill it with a test, or say in
# docs/journal.md ("cargo-mutants") why it is harmless.
#
# Needs cargo-mutants (`cargo install cargo-mutants --locked`, version 27 here).
set -euo pipefail
cd "$(dirname "$0")/.."

base=HEAD~1
full=false
for a in "$@"; do
  case "$a" in
    --full) full=true ;;
    *) base=$a ;;
  esac
done
command -v cargo-mutants >/dev/null || {
  echo "cargo-mutants is not installed: cargo install cargo-mutants --locked" >&2
  exit 2
}

out=target/mutants-touched
mkdir -p "$out"
export CARGO_INCREMENTAL=0 CARGO_PROFILE_DEV_DEBUG=0
status=0
# One package a time: each runs its own tests.
for spec in "slamesh-core core/" "slamesh std-adapters/"; do
  read -r package dir <<<"$spec"
  diff="$out/$package.diff"
  git diff "$base" -- "$dir" ':(exclude)*/tests/*' > "$diff"
  if ! grep -q '^+' "$diff"; then
    echo "$package: no line changed since $base"
    continue
  fi
  args=()
  if [ "$package" = slamesh ] && ! $full; then
    args=(-- --lib)
  fi
  echo "$package: mutants on the lines changed since $base"
  if ! cargo mutants -p "$package" --in-diff "$diff" -j 1 --timeout 300 \
      -o "$out/$package" "${args[@]}"; then
    status=1
    echo "$package: survivors (missed), in $out/$package/mutants.out/missed.txt:"
    cat "$out/$package/mutants.out/missed.txt" 2>/dev/null || true
  fi
done
exit $status
