#!/usr/bin/env bash
# The named mutations (issue 87; std-adapters/src/mutants.rs): builds the tests and the command
# once with the feature `mutants`, then for each mutation runs, with SLAMESH_MUTANT=NAME, every
# test that must catch it, and fails unless each of them fails (within its time). Needs
# SLAMESH_DATA (the tests' data); `stamp-f64`'s ROS 2 check needs root (unshare -n) and the
# rclpy environment tests/ros2 uses (target/ros2-py). Leaves target/debug/slamesh built with
# the mutations: build it again before using it.
#   tools/named_mutations.sh [NAME...]      (default: every mutation the suite catches)
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}" CARGO_PROFILE_DEV_DEBUG="${CARGO_PROFILE_DEV_DEBUG:-0}"
: "${SLAMESH_DATA:?set SLAMESH_DATA to the folder of the test data}"
features=slamesh/view,slamesh/mutants
py=${ROS2_PYTHON:-target/ros2-py/bin/python}

# The tests that must fail under each mutation ("ros2:N": tests/ros2's check N).
tests_of() {
  case "$1" in
    edge-band) echo "navmap::the_town_s_navigation_map_against_the_truth navmap::the_office_s_navigation_map_against_the_truth" ;;
    gyro-scale) echo "imu::a_shaken_sweep_with_its_imu_tracks_as_well_as_a_calm_one imu_data::a_kitti_raw_drive_is_read_with_its_oxts_packets_and_timed_from_its_sweep" ;;
    window-never-evicts) echo "map_persistence::a_windowed_run_saves_the_cells_it_evicted command_outputs::window_flags_and_the_memory_cap_from_the_command_line" ;;
    stamp-f64) echo "ros2:5" ;;
    # No drive of the suite proposes a revisit its checks refuse (docs/journal.md, "Named
    # mutations"): the checks themselves are tested on a scan of another place.
    closure-unverified) echo "closure_checks::a_revisit_is_a_closure_only_when_the_search_vouches_for_it" ;;
    *) echo "unknown mutation $1" >&2; exit 2 ;;
  esac
}

if [ $# -gt 0 ]; then
  names=("$@")
else
  names=(edge-band gyro-scale window-never-evicts stamp-f64 closure-unverified)
fi

# Built as CI's tests step builds (the workspace's tests, these features), so that in CI this
# is that build, not another; the integration tests' build has the command too.
cargo test -q --workspace --tests --features "$features" --no-run
test_bin=$(cargo test --workspace --tests --features "$features" --no-run 2>&1 \
  | sed -n 's/.*Executable .*tests\/integration.rs (\(.*\))$/\1/p' | tail -n 1)
[ -x "$test_bin" ] || { echo "cannot find the integration tests' binary" >&2; exit 1; }

# tests/ros2's check $2 against the command with mutation $1, in a loopback-only namespace.
ros2_check() {
  rm -rf target/mutants-ros2; mkdir -p target/mutants-ros2
  SLAMESH_MUTANT="$1" timeout 120 unshare -n bash -c '
    ip link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo
    export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
    exec "$0" tests/ros2/check_node.py --slamesh target/debug/slamesh --python "$0" \
      --data "$1" --work target/mutants-ros2 --only "$2"' "$py" "$SLAMESH_DATA" "$2"
}

# Without a mutation every one of those tests passes: a failure under a mutation is the
# mutation's. SLAMESH_MUTANTS_BASELINE=done skips that pass where the caller has just run them
# on this build (CI's tests step and its ROS 2 step).
all=()
for name in "${names[@]}"; do for t in $(tests_of "$name"); do all+=("$t"); done; done
plain=(); ros2=()
for t in "${all[@]}"; do [[ $t == ros2:* ]] && ros2+=("${t#ros2:}") || plain+=("$t"); done
if [ "${SLAMESH_MUTANTS_BASELINE:-}" = done ]; then
  echo "without a mutation: the ${#all[@]} tests of the set passed on this build before (the caller says)"
else
  if [ ${#plain[@]} -gt 0 ]; then
    env -u SLAMESH_MUTANT "$test_bin" --exact "${plain[@]}" -q >/dev/null 2>&1 \
      || { echo "without a mutation, a test of the set fails: ${plain[*]}" >&2; exit 1; }
  fi
  for n in ${ros2[@]+"${ros2[@]}"}; do
    ros2_check none "$n" >/dev/null 2>&1 || { echo "without a mutation, tests/ros2 check $n fails" >&2; exit 1; }
  done
  echo "without a mutation: the ${#all[@]} tests of the set pass"
fi

survived=()
for name in "${names[@]}"; do
  tests=$(tests_of "$name")
  [ -n "$tests" ] || { echo "$name: no test catches it yet"; survived+=("$name"); continue; }
  for t in $tests; do
    start=$SECONDS
    if [[ $t == ros2:* ]]; then
      if ros2_check "$name" "${t#ros2:}" >/dev/null 2>&1; then
        echo "$name: tests/ros2 check ${t#ros2:} passed: the mutation SURVIVED"; survived+=("$name:$t")
      else
        echo "$name: caught by tests/ros2 check ${t#ros2:} ($((SECONDS - start)) s)"
      fi
    elif SLAMESH_MUTANT=$name timeout 300 "$test_bin" --exact "$t" -q >/dev/null 2>&1; then
      echo "$name: $t passed: the mutation SURVIVED"; survived+=("$name:$t")
    else
      echo "$name: caught by $t ($((SECONDS - start)) s)"
    fi
  done
done
if [ ${#survived[@]} -gt 0 ]; then
  printf 'survived: %s\n' "${survived[@]}"
  exit 1
fi
echo "every named mutation was caught"
