"""The navigation map read back as Nav2 and GIS tools read it, with numpy alone: the PGM's
header and bytes, the YAML's keys, `map_server`'s trinary rule, and the ESRI elevation grids
over the same cells."""

import json

import numpy as np

from conftest import FIXTURES


def read_pgm(path):
    """A binary PGM (P5) as a uint8 array, rows top-down."""
    data = path.read_bytes()
    fields, at = [], 0
    while len(fields) < 4:
        while data[at : at + 1].isspace():
            at += 1
        if data[at : at + 1] == b"#":
            at = data.index(b"\n", at)
            continue
        end = at
        while not data[end : end + 1].isspace():
            end += 1
        fields.append(data[at:end].decode())
        at = end
    assert fields[0] == "P5" and fields[3] == "255"
    width, height = int(fields[1]), int(fields[2])
    return np.frombuffer(data[at + 1 :], dtype=np.uint8).reshape(height, width)


def read_yaml(path):
    """The map YAML's `key: value` lines (comments left out)."""
    out = {}
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            key, value = line.split(":", 1)
            out[key.strip()] = value.strip()
    return out


def test_the_navigation_map_loads_as_map_server_loads_it(tmp_path, command):
    command(
        ["run", FIXTURES / "recordings" / "scans", "--out", tmp_path, "--navmap", "--no-picture"],
        tmp_path,
    )
    meta = read_yaml(tmp_path / "map.yaml")
    assert meta["image"] == "map.pgm" and meta["mode"] == "trinary" and meta["negate"] == "0"
    pixels = read_pgm(tmp_path / meta["image"])
    assert set(np.unique(pixels)) <= {0, 205, 254}
    # map_server's trinary rule: occ = (255 - p) / 255; occupied above occupied_thresh, free
    # below free_thresh, unknown between.
    occ = (255.0 - pixels) / 255.0
    occupied = occ > float(meta["occupied_thresh"])
    free = occ < float(meta["free_thresh"])
    unknown = ~occupied & ~free
    assert (unknown == (pixels == 205)).all(), "an unknown pixel would load as known"
    assert free.sum() > 1000 and occupied.sum() > 100
    summary = json.loads((tmp_path / "navmap.json").read_text())
    assert (summary["free"], summary["occupied"], summary["unknown"]) == (
        int(free.sum()),
        int(occupied.sum()),
        int(unknown.sum()),
    )
    # The origin is the lower-left pixel's corner; the elevation grids cover the same cells.
    origin = [float(v) for v in meta["origin"].strip("[]").split(",")]
    assert origin[:2] == summary["origin"] and origin[2] == 0.0
    header = (tmp_path / "elevation.asc").read_text().splitlines()[:6]
    head = {line.split()[0]: float(line.split()[1]) for line in header}
    assert (head["ncols"], head["nrows"]) == (pixels.shape[1], pixels.shape[0])
    assert (head["xllcorner"], head["yllcorner"]) == tuple(origin[:2])
    height = np.loadtxt(tmp_path / "elevation.asc", skiprows=6, ndmin=2)
    variance = np.loadtxt(tmp_path / "elevation_variance.asc", skiprows=6, ndmin=2)
    assert height.shape == pixels.shape == variance.shape
    seen = height != head["NODATA_value"]
    # Ground is where the map is free, or unknown within two cells (0.2 m) of an occupied one
    # (an obstacle's edge): never in unknown space away from obstacles.
    edge = np.zeros_like(occupied)
    rows, cols = occupied.shape
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            if dx * dx + dy * dy <= 4:
                shifted = np.zeros_like(occupied)
                shifted[max(dy, 0) : rows + min(dy, 0), max(dx, 0) : cols + min(dx, 0)] = occupied[
                    max(-dy, 0) : rows + min(-dy, 0), max(-dx, 0) : cols + min(-dx, 0)
                ]
                edge |= shifted
    assert not (seen & unknown & ~edge).any()
    assert (seen & free).sum() >= 0.8 * free.sum(), "free cells without a ground height"
    assert (variance[seen] >= 0).all() and np.isfinite(height[seen]).all()
