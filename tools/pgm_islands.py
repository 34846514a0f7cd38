#!/usr/bin/env python3
"""Counts a Nav2 map's cells by kind and its small islands of unknown inside free space.

    tools/pgm_islands.py OUT/map.pgm [MORE.pgm ...]

Reads a trinary `map.pgm` as `slamesh run --navmap` and `slamesh navmap` write it (254 free,
0 occupied, 205 unknown) and prints, for each file, the free, occupied and unknown cells and
the islands: groups of one to four unknown cells, joined side to side, that touch only free
cells and not the image's edge. A planner that keeps unknown space out of its paths sees each
as a post in open floor; docs/journal.md ("Where voxel cells' seams cross") counts them. With
the standard library alone, so the tool needs no package.
"""
import re
import sys

FREE, OCCUPIED, UNKNOWN = 254, 0, 205
MOST = 4


def read_pgm(path):
    data = open(path, "rb").read()
    m = re.match(rb"P5\s+(?:#.*\n\s*)*(\d+)\s+(\d+)\s+(\d+)\s", data)
    if not m:
        sys.exit(f"{path}: not a binary PGM")
    width, height, _ = map(int, m.groups())
    return width, height, data[m.end():m.end() + width * height]


def islands(width, height, px):
    """Groups of at most MOST unknown cells that touch free cells only."""
    seen = bytearray(width * height)
    count = 0
    for start in range(width * height):
        if px[start] != UNKNOWN or seen[start]:
            continue
        seen[start] = 1
        group, enclosed, i = [start], True, 0
        while i < len(group):
            y, x = divmod(group[i], width)
            i += 1
            for yy, xx in ((y, x + 1), (y, x - 1), (y + 1, x), (y - 1, x)):
                if not (0 <= yy < height and 0 <= xx < width):
                    enclosed = False
                    continue
                k = yy * width + xx
                if px[k] == UNKNOWN:
                    if not seen[k]:
                        seen[k] = 1
                        group.append(k)
                elif px[k] != FREE:
                    enclosed = False
        count += int(enclosed and len(group) <= MOST)
    return count


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for path in sys.argv[1:]:
        width, height, px = read_pgm(path)
        kinds = {v: px.count(v) for v in (FREE, OCCUPIED, UNKNOWN)}
        print(
            f"{path}: {width} x {height}, free {kinds[FREE]}, occupied {kinds[OCCUPIED]}, "
            f"unknown {kinds[UNKNOWN]}, islands of unknown in free space {islands(width, height, px)}"
        )


if __name__ == "__main__":
    main()
