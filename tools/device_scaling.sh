#!/usr/bin/env bash
# Thread scaling of one or more builds on a many-core machine (issue 58; docs/journal.md,
# "All the cores"), run from a folder that holds what it needs:
#   slamesh-NAME (or slamesh-NAME.gz): each build, stripped (`strip -o DIR/slamesh-A
#     target/release/slamesh`), gzipped to travel light if need be;
#   write_drive (or .gz): `cargo build --release --example write_drive`, stripped;
#   kitti00/: a copy of kitti-mini's sequence 00;
#   pool_wake (or .gz), optional: `cargo build --release --example pool_wake`, stripped: how
#     late the pool's idle threads join a loop, at 2 to 16 threads, sleeping and hovering.
# It writes the 400-frame 64-beam town (`write_drive --azimuth-steps 2000`), runs `bench
# --scaling` on kitti00 with each build, then `slamesh run` on the town at 1, 2, 4, 8 and 16
# threads, two rounds alternating the builds, checks that every thread count wrote the poses
# and mesh of one thread, and leaves each run's report.json in $OUT/reports.tgz (the medians of
# their per-frame stage medians are the figures quoted).
#
#   BINS="A B" OUT=/tmp/out DIR/device_scaling.sh      (after copying this script into DIR)
set -u
cd "$(dirname "$0")"
for z in *.gz; do [ -e "$z" ] && gunzip -kf "$z"; done
chmod +x slamesh-* write_drive
[ -e pool_wake ] && chmod +x pool_wake
bins=${BINS:-"A B"}
echo "cores: $(nproc)"; lscpu | grep -E "Model name|L3|Socket|Thread" || true
t0=$SECONDS
if [ -x pool_wake ]; then
  for t in 2 4 8 16; do ./pool_wake --threads "$t"; ./pool_wake --threads "$t" --hover; done \
    > "$OUT/wake.txt" 2>&1
  cat "$OUT/wake.txt"
fi
./write_drive --out /tmp/town --frames "${FRAMES:-400}" --azimuth-steps 2000 >/dev/null
echo "town written in $((SECONDS - t0)) s"
for b in $bins; do
  ./slamesh-"$b" bench kitti00 --preset kitti --scaling --repeat 3 > "$OUT/kitti-$b.txt" 2>&1
  cat "$OUT/kitti-$b.txt"
done
mkdir -p /tmp/reports
for round in 1 2; do
  for b in $bins; do
    for t in 1 2 4 8 16; do
      o=/tmp/o-$b-$t
      rm -rf "$o"
      s=$SECONDS
      ./slamesh-"$b" run /tmp/town --out "$o" --threads "$t" -q --no-picture >/dev/null 2>&1
      echo "town $b t$t round $round: $((SECONDS - s)) s"
      cp "$o/report.json" "/tmp/reports/town-$b-t$t-r$round.json"
    done
    for t in 2 4 8 16; do
      if cmp -s "/tmp/o-$b-1/poses_kitti.txt" "/tmp/o-$b-$t/poses_kitti.txt" \
        && cmp -s "/tmp/o-$b-1/mesh.ply" "/tmp/o-$b-$t/mesh.ply"; then
        echo "$b t$t: same poses and mesh as t1"
      else
        echo "$b t$t: DIFFERS from t1"
      fi
    done
  done
done
tar czf "$OUT/reports.tgz" -C /tmp reports
echo "total $((SECONDS - t0)) s"
