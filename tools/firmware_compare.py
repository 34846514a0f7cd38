#!/usr/bin/env python3
"""Compares the firmware's f64 and f32 builds (examples/firmware), as .ci/run runs them.

    tools/firmware_compare.py F64_LOG F64_MAP F32_LOG F32_MAP

Each LOG is what `cargo run --release [--features f64]` printed under QEMU; each MAP the
linker map of that build. Prints, per build, the footprint (flash: .vector_table, .text,
.rodata and .data's initial values; RAM: .data and .bss), the median instructions per real
scan and the mean and worst step errors, then the ratios.

Exits 1 unless the f32 build meets issue 40's targets against the f64 build of the same run:
median instructions per scan at most a third, mean step error at most 10 % above, the worst
step under 5 cm and 0.5 degree (the firmware checks these itself too), and flash and RAM no
larger. Exits 2 if a log has no real-scan summary (the firmware was built without
SLAMESH_DATA).
"""
import re
import sys

SUMMARY = re.compile(
    r"real scans: step error mean ([\d.]+) cm, worst ([\d.]+) cm and ([\d.]+) deg .*?"
    r"median (\d+) instructions a scan")
SECTION = re.compile(r"^\s*[0-9a-f]+\s+[0-9a-f]+\s+([0-9a-f]+)\s+\d+ (\.[a-z_]+)$", re.M)


def footprint(map_path):
    sizes = {name: int(size, 16) for size, name in SECTION.findall(open(map_path).read())}
    flash = sum(sizes.get(s, 0) for s in (".vector_table", ".text", ".rodata", ".data"))
    ram = sum(sizes.get(s, 0) for s in (".data", ".bss"))
    return flash, ram, sizes


def summary(log_path):
    m = SUMMARY.search(open(log_path).read())
    if not m:
        print(f"{log_path}: no real-scan summary (was SLAMESH_DATA set for the build?)",
              file=sys.stderr)
        sys.exit(2)
    return float(m[1]), float(m[2]), float(m[3]), int(m[4])


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    builds = {}
    for name, log, map_path in (("f64", sys.argv[1], sys.argv[2]), ("f32", sys.argv[3], sys.argv[4])):
        builds[name] = (summary(log), footprint(map_path))
    print(f"{'build':<6} {'median instructions/scan':>25} {'mean step cm':>13} "
          f"{'worst cm':>9} {'worst deg':>10} {'flash B':>9} {'RAM B':>9}")
    for name, ((mean, worst_cm, worst_deg, median), (flash, ram, sizes)) in builds.items():
        print(f"{name:<6} {median:>25,} {mean:>13.2f} {worst_cm:>9.2f} {worst_deg:>10.3f} "
              f"{flash:>9,} {ram:>9,}   (.text {sizes.get('.text', 0)}, "
              f".rodata {sizes.get('.rodata', 0)}, .bss {sizes.get('.bss', 0)})")
    (m64, _, _, i64), (f64_flash, f64_ram, _) = builds["f64"]
    (m32, w32_cm, w32_deg, i32_), (f32_flash, f32_ram, _) = builds["f32"]
    ratio = i32_ / i64
    print(f"f32 / f64: instructions {ratio:.3f} (target at most 1/3), mean step error "
          f"{m32 / m64:.3f} (at most 1.10), flash {f32_flash / f64_flash:.3f}, "
          f"RAM {f32_ram / f64_ram:.3f} (each at most 1)")
    failures = []
    if ratio > 1 / 3:
        failures.append(f"instructions a scan {ratio:.3f} of the f64 build's, over 1/3")
    if m32 > 1.10 * m64:
        failures.append(f"mean step error {m32} cm, over 110 % of the f64 build's {m64} cm")
    if w32_cm >= 5.0 or w32_deg >= 0.5:
        failures.append(f"worst step {w32_cm} cm, {w32_deg} deg: not under 5 cm and 0.5 deg")
    if f32_flash > f64_flash or f32_ram > f64_ram:
        failures.append("the f32 build's flash or RAM is larger than the f64 build's")
    for f in failures:
        print(f"FAIL: {f}", file=sys.stderr)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
