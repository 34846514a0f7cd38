#!/usr/bin/env python3
"""Counts and draws the cells a navigation-map test scored (tests/navmap.rs).

    SLAMESH_NAVMAP_DIAG=/tmp/diag cargo test --release -p slamesh --test integration -- navmap
    tools/navmap_cells.py /tmp/diag/navmap-office [--scale 3]

Reads DIR/cells.csv (kind; the column and row from the bottom in the grid; the centre in the
world: every seen cell the map or the truth calls occupied) and prints the count of each kind
and the IoU they make, then writes DIR/cells.png, one square per cell as the grid lies (its
rows up), cropped to the cells listed: black where both say occupied (`hit`), red where only
the map does (`false`), blue where only the truth does (`missed`). The picture is written with the standard library alone (zlib), so the tool needs
no package.
"""
import argparse
import collections
import csv
import os
import struct
import zlib

COLOURS = {"hit": (0, 0, 0), "false": (220, 30, 30), "missed": (30, 60, 230)}


def write_png(path, rows):
    """Writes `rows` (lists of (r, g, b)) as an 8-bit RGB PNG."""
    height, width = len(rows), len(rows[0])
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)

    def chunk(tag, data):
        body = tag + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", help="a folder the test left (SLAMESH_NAVMAP_DIAG/NAME)")
    ap.add_argument("--scale", type=int, default=3, help="pixels a cell (default 3)")
    args = ap.parse_args()

    with open(os.path.join(args.dir, "cells.csv")) as f:
        cells = [(r["kind"], int(r["column"]), int(r["row"])) for r in csv.DictReader(f)]
    if not cells:
        raise SystemExit(f"{args.dir}/cells.csv: no cells")
    counts = collections.Counter(kind for kind, _, _ in cells)
    hit, false, missed = (counts.get(k, 0) for k in ("hit", "false", "missed"))
    print(f"hit {hit}, false {false}, missed {missed}: IoU {hit / (hit + false + missed):.3f}")

    c0 = min(c for _, c, _ in cells)
    r0 = min(r for _, _, r in cells)
    width = max(c for _, c, _ in cells) - c0 + 1
    height = max(r for _, _, r in cells) - r0 + 1
    grid = [[(255, 255, 255)] * width for _ in range(height)]
    for kind, c, r in cells:
        grid[height - 1 - (r - r0)][c - c0] = COLOURS[kind]
    s = args.scale
    rows = [[grid[r // s][c // s] for c in range(width * s)] for r in range(height * s)]
    out = os.path.join(args.dir, "cells.png")
    write_png(out, rows)
    print(f"wrote {out} ({width} x {height} cells from column {c0}, row {r0})")


if __name__ == "__main__":
    main()
