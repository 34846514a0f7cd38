"""Writes the starting corpus of each fuzz target into fuzz/corpus/<target>/ (run from fuzz/).

The seeds are small valid inputs: a slice of a real KITTI scan, the same points as PCD (three
encodings) and PLY (ascii, both binary byte orders, with faces), the three preset TOML files,
and scans for the core target. libFuzzer grows the corpus from them.
"""
import os, struct, subprocess, sys

DATA = os.environ.get("SLAMESH_DATA", "../../shared/data")
out = "corpus"


def put(target, name, data):
    os.makedirs(f"{out}/{target}", exist_ok=True)
    with open(f"{out}/{target}/{name}", "wb") as f:
        f.write(data)


raw = open(f"{DATA}/kitti-mini/00/velodyne/000000.bin", "rb").read()
records = [raw[i:i + 16] for i in range(0, len(raw), 16)]
pts = [struct.unpack("<3f", r[:12]) for r in records[::500][:200]]
put("kitti_bin", "slice", b"".join(records[::500][:200]))
put("kitti_bin", "one", records[0])

head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        "WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {e}\n")
few = pts[:24]
put("pcd", "ascii", (head.format(n=len(few), e="ascii")
                     + "".join(f"{x} {y} {z}\n" for x, y, z in few)).encode())
put("pcd", "binary", head.format(n=len(few), e="binary").encode()
    + b"".join(struct.pack("<3f", *p) for p in few))
soa = b"".join(struct.pack("<f", p[c]) for c in range(3) for p in few)
lzf = b"".join(bytes([len(soa[i:i + 32]) - 1]) + soa[i:i + 32] for i in range(0, len(soa), 32))
put("pcd", "binary_compressed", head.format(n=len(few), e="binary_compressed").encode()
    + struct.pack("<II", len(lzf), len(soa)) + lzf)

tri = [(0, 1, 2), (1, 2, 3)]
verts = few[:4]
def ply(fmt, body):
    return (f"ply\nformat {fmt} 1.0\nelement vertex {len(verts)}\nproperty float x\n"
            "property float y\nproperty float z\nelement face 2\n"
            "property list uchar int vertex_indices\nend_header\n").encode() + body
put("ply", "ascii", ply("ascii", ("".join(f"{x} {y} {z}\n" for x, y, z in verts)
                                  + "".join(f"3 {a} {b} {c}\n" for a, b, c in tri)).encode()))
for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
    body = b"".join(struct.pack(e + "3f", *v) for v in verts)
    body += b"".join(struct.pack(e + "B3i", 3, *t) for t in tri)
    put("ply", fmt, ply(fmt, body))

for preset in ("default", "kitti", "meshing"):
    text = subprocess.run([sys.argv[1], "config", "--preset", preset], check=True,
                          capture_output=True).stdout
    put("config_toml", preset, text)
put("config_toml", "window", b'preset = "kitti"\n[window]\nevict_after = 50\n')

# Core: mode byte 1 (centimetre i16 coordinates), two scans of the same points, the second
# moved 10 cm; mode 3 with the meshing preset; mode 0 raw f32.
def cm(points, dx=0.0):
    return b"".join(struct.pack("<3h", *(max(-32768, min(32767, round(v * 100)))
                                         for v in (x + dx, y, z))) for x, y, z in points)
near = [p for p in (struct.unpack("<3f", r[:12]) for r in records[::60]) if max(map(abs, p)) < 300][:600]
scan = cm(near).replace(b"\xfe", b"\xfd")
moved = cm(near, 0.1).replace(b"\xfe", b"\xfd")
put("core_scan", "two_scans", b"\x01" + scan + b"\xfe" + moved)
put("core_scan", "meshing", b"\x07" + scan + b"\xfe" + moved + b"\xfe" + scan)
put("core_scan", "raw", b"\x00" + b"".join(struct.pack("<3f", *p) for p in near[:100]))

# Recordings: the small malformed-fixture MCAP files (made by tests/fixtures/recordings/make.py)
# without their magic (the target puts it back, choosing by the first byte: odd for MCAP), and
# their PointCloud2 messages for the decoder.
fixtures = "../tests/fixtures/recordings/bad"
for name in ["two-clouds.mcap", "short-data.mcap"]:
    mcap = open(f"{fixtures}/{name}", "rb").read()
    put("recording", name, b"\x01" + mcap[8:])
# A ROS 2 .db3 file (SQLite; the first byte 2 picks its magic, 16 bytes).
db3 = open("../tests/fixtures/recordings/ros2-db3/split_1.db3", "rb").read()
put("recording", "split_1.db3", b"\x02" + db3[16:])
try:
    from mcap.reader import make_reader
    with open(f"{fixtures}/two-clouds.mcap", "rb") as f:
        for k, (_, channel, message) in enumerate(make_reader(f).iter_messages()):
            if channel.topic.endswith("points"):
                put("pointcloud2", f"cdr{k}", message.data)
except ImportError:
    print("pip install mcap for the pointcloud2 seeds", file=sys.stderr)

# A map file, written here from the format's table in core/src/map_file/mod.rs (not by slamesh):
# a check, too, that its checksums are the standard CRC-32 (zlib's). Two cells in one tile, a
# path of two poses.
import zlib


def block(body):
    return body + struct.pack("<I", zlib.crc32(body))


config = b'preset = "default"\n'
frame = b"map"
hbody = struct.pack("<dBIH", 1.6, 0, 2, len(frame)) + frame + struct.pack("<I", len(config)) + config


def map_file(version):
    """Version 1: a cell's axes byte alone; version 2: bit 7 set and a byte of facings after it
    (two bits per axis: 1 facing +axis, 2 -axis, 3 both)."""
    header = block(b"SLMSHMAP" + struct.pack("<II", version, len(hbody)) + hbody)
    cells = b""
    for key, mask, facings in (((0, 1, 0), 4, 0b010000), ((3, 1, 0), 5, 0b010011)):
        layers = bin(mask).count("1")
        cells += struct.pack("<3iIB", *key, 1, mask | (0x80 if version > 1 else 0))
        if version > 1:
            cells += struct.pack("<B", facings)
        for _ in range(layers):
            cells += struct.pack("<36f", *[0.4 + 0.01 * j for j in range(36)])
            cells += struct.pack("<36f", *[0.05] * 36)
    tile = block(b"TILE" + struct.pack("<3iII", 0, 0, 0, 2, len(cells)) + cells)
    path_offset = len(header) + len(tile)
    path = block(b"PATH" + struct.pack("<I", 2) + struct.pack("<8d", 0.0, 0, 0, 1.7, 0, 0, 0, 1)
                 + struct.pack("<8d", 0.1, 1.0, 0, 1.7, 0, 0, 0, 1))
    index_offset = path_offset + len(path)
    index = block(b"INDX" + struct.pack("<I", 1) + struct.pack("<3iQI", 0, 0, 0, len(header), len(tile)))
    trailer = block(struct.pack("<QQ", index_offset, path_offset)) + b"MEND"
    return header + tile + path + index + trailer


put("map_file", "two_cells", map_file(1))
put("map_file", "two_cells_v2", map_file(2))

# The scans' floor beside a saved map, from the table in std-adapters/src/navmap/floor_file.rs:
# two floors (one seen twice) that go with a path of two poses, and none at all.
def floor_file(floors):
    body = b"SLMFLOOR" + struct.pack("<IdQd", 1, 0.1, 2, 0.1)
    body += b"".join(struct.pack("<3fB", *at, twice) for at, twice in floors)
    return block(body)


put("floor_file", "two", floor_file([((1.05, -2.25, -1.49), 1), ((3.5, 0.15, 0.01), 0)]))
put("floor_file", "none", floor_file([]))


# Packets: the first frames of a real HDL-32E capture (tests/fixtures/packets), as pcap and
# pcapng, and one data packet alone.
cap = open("../tests/fixtures/packets/hdl32e-street.pcap", "rb").read()
frames, off = [], 24
while off + 16 <= len(cap) and len(frames) < 6:
    incl, = struct.unpack("<I", cap[off + 8:off + 12])
    frames.append(cap[off:off + 16 + incl])
    off += 16 + incl
put("capture", "pcap", cap[:24] + b"".join(frames))
ng = open("../tests/fixtures/packets/hdl32e-street.pcapng", "rb").read()
put("capture", "pcapng", ng[:8000])
data = next(f[16 + 42:] for f in frames if len(f) == 16 + 1248)
put("velodyne_packet", "hdl32e", data)


# Ouster: one lidar packet of each fixture capture (its profile and beams picked by the first
# byte, as the target reads it), and each fixture's metadata JSON.
PROFILES = ["LEGACY", "RNG19_RFL8_SIG16_NIR16", "RNG19_RFL8_SIG16_NIR16_DUAL", "RNG15_RFL8_NIR8",
            "RNG15_RFL8_NIR8_DUAL"]
for name, profile, beams in [("ouster-os1-32-legacy", "LEGACY", 32),
                             ("ouster-os0-32-dual", "RNG19_RFL8_SIG16_NIR16_DUAL", 32),
                             ("ouster-os2-128-rng19", "RNG19_RFL8_SIG16_NIR16", 128),
                             ("ouster-os1-128-lowdata", "RNG15_RFL8_NIR8", 128)]:
    cap = open(f"../tests/fixtures/packets/{name}.pcap", "rb").read()
    off, packet = 24, None
    while off + 16 <= len(cap) and packet is None:
        incl, = struct.unpack("<I", cap[off + 8:off + 12])
        if incl > 1000:
            packet = cap[off + 16 + 42:off + 16 + incl]
        off += 16 + incl
    pick = PROFILES.index(profile) + 8 * [16, 32, 64, 128].index(beams)
    put("ouster_packet", name, bytes([pick]) + packet)
    put("ouster_metadata", name, open(f"../tests/fixtures/packets/{name}.json", "rb").read())

# An Ouster's IMU packets: the moving OS1-128's 30 (port 7503), one after another; four of
# them after its transform.
cap = open("../tests/fixtures/packets/ouster-os1-128-lowdata.pcap", "rb").read()
off, imu = 24, []
while off + 16 <= len(cap):
    incl, = struct.unpack("<I", cap[off + 8:off + 12])
    if struct.unpack(">H", cap[off + 16 + 36:off + 16 + 38])[0] == 7503:
        imu.append(cap[off + 16 + 42:off + 16 + incl])
    off += 16 + incl
put("ouster_imu_packet", "os1-128", b"\x00" + b"".join(imu))
identity = struct.pack("<16d", *[1.0 if k % 5 == 0 else 0.0 for k in range(16)])
put("ouster_imu_packet", "os1-128-transform", b"\x01" + identity + b"".join(imu[:4]))


# The HDL-64E: a data packet of the capture made in tests/fixtures/packets (the target decodes
# it with that folder's calibration), and the calibration itself, block style and flow style.
cap = open("../tests/fixtures/packets/hdl64e-s2-street.pcap", "rb").read()
incl, = struct.unpack("<I", cap[24 + 8:24 + 12])
put("velodyne_packet", "hdl64e", cap[24 + 16 + 42:24 + 16 + incl])
calib = open("../tests/fixtures/packets/hdl64e-s2.1-sztaki.yml", "rb").read()
put("velodyne_calibration", "block", calib)
put("velodyne_calibration", "flow", b"distance_resolution: 0.002\nlasers:\n"
    + b"".join(b"- {laser_id: %d, rot_correction: -0.07, vert_correction: %f, "
               b"dist_correction: 1.4, dist_correction_x: 1.42, dist_correction_y: 1.41, "
               b"vert_offset_correction: 0.21, horiz_offset_correction: 0.026}\n"
               % (i, -0.4 + i * 0.01) for i in range(64)))


# IMU readings as EuRoC's imu0/data.csv writes them (imu_csv): a header, readings 5 ms apart,
# one out of order, one duplicate, one short line.
put("imu_csv", "euroc", b"#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],"
    b"w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n"
    + b"".join(b"%d,%.6f,%.6f,%.6f,%.4f,%.4f,%.4f\n"
               % (1403636579758555392 + k * 5000000, 0.01 * k, -0.02, 0.3, 0.1, -0.2, 9.81)
               for k in range(40))
    + b"1403636579758555392,0,0,0,0,0,9.8\n1403636579953555392,1,2,3\n")


# sensor_msgs/Imu as ROS 1 and CDR serialise it (imu_message): the stamp, the frame, then the
# orientation, the rates and their covariances (37 doubles).
imu_doubles = [0, 0, 0, 1] + [0] * 9 + [0.1, -0.2, 0.3] + [0] * 9 + [0.4, 0.5, 9.81] + [0] * 9
put("imu_message", "ros1", struct.pack("<IIII", 7, 1317000000, 250000000, 3) + b"imu"
    + struct.pack("<37d", *imu_doubles))
put("imu_message", "cdr", bytes([0, 1, 0, 0]) + struct.pack("<iII", 1317000000, 250000000, 4)
    + b"imu\0" + struct.pack("<37d", *imu_doubles))


# The ROS 2 node's command line and a parameter file (ros_args).
put("ros_args", "command_line", b"--ros-args -r points:=/velodyne_points -p threads:=2 "
    b"-p preset:=kitti -r __ns:=/robot1 -p lidar_in_base:=[0.0,0,1.2,0,0,0]")
put("ros_args", "params_file", open("../examples/ros2/params.yaml", "rb").read())


# The messages the ROS 2 node takes, in little-endian CDR as ROS 2 writes them (ros_messages):
# an `initialpose` (PoseWithCovarianceStamped) and an `imu` reading.
class Cdr:
    def __init__(self):
        self.b = bytearray()

    def put(self, fmt, *v):
        size = struct.calcsize("<" + fmt[-1])
        self.b += b"\0" * (-len(self.b) % size)
        self.b += struct.pack("<" + fmt, *v)
        return self

    def string(self, s):
        data = s.encode() + b"\0"
        return self.put("I", len(data)).raw(data)

    def raw(self, data):
        self.b += data
        return self


header = lambda c, frame: c.put("iI", 12, 500000000).string(frame)
pose = header(Cdr(), "map").put("7d", 2.0, 0.5, 0.0, 0.0, 0.0, 0.38, 0.92).put("36d", *([0.1] * 36))
put("ros_messages", "initialpose", bytes(pose.b))
imu = (header(Cdr(), "imu").put("4d", 0, 0, 0, 1).put("9d", *([-1.0] + [0.0] * 8))
       .put("3d", 0.01, -0.02, 0.3).put("9d", *([0.0] * 9)).put("3d", 0.1, 0.2, 9.81)
       .put("9d", *([0.0] * 9)))
put("ros_messages", "imu", bytes(imu.b))


# A checkpoint (checkpoint): written by the build itself, in the format it writes, with the
# IMU stage's real state (`cargo test -p slamesh --lib write_the_checkpoint_fuzz_seed --
# --ignored`, std-adapters/src/inertial/stage.rs), where a hand-made one went stale with each
# version of the format.


# Trajectories as `slamesh eval` reads them (trajectory): estimate, reference and calib.txt
# between zero bytes. kitti-mini 00's first six camera poses with its calib.txt; the same
# positions as TUM lines with stamps, the reference's a frame late; and a KITTI estimate paired
# with a TUM reference by line.
kitti_poses = open(f"{DATA}/kitti-mini/00/poses.txt", "rb").read().splitlines(keepends=True)[:6]
calib = open(f"{DATA}/kitti-mini/00/calib.txt", "rb").read()
tum = [f"{0.1 * i:.1f} {r.split()[3].decode()} {r.split()[7].decode()} {r.split()[11].decode()} 0 0 0 1\n"
       for i, r in enumerate(kitti_poses)]
put("trajectory", "kitti_calib", b"".join(kitti_poses) + b"\0" + b"".join(kitti_poses) + b"\0" + calib)
put("trajectory", "tum", ("# t x y z qx qy qz qw\n" + "".join(tum)).encode() + b"\0"
    + "".join(tum[1:]).encode())
put("trajectory", "kitti_tum", b"".join(kitti_poses) + b"\0" + "".join(tum).encode())
