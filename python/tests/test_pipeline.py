"""The pipeline from Python: the command's poses and mesh to the byte, bad arrays refused
with a clear message while the pipeline goes on, the mesh's arrays round-tripping through a
file, and the GIL released while it works."""

import filecmp
import threading
import time

import numpy as np
import pytest

import slamesh
from conftest import FIXTURES, data_folder

SCANS = FIXTURES / "recordings" / "scans"

# Every kind of input the command reads, each a committed fixture: a folder of KITTI .bin
# scans, a ROS 1 bag, an MCAP file, ROS 2 bag folders (.db3 and .mcap), and packet captures of
# a Velodyne and of an Ouster (with its metadata beside it).
INPUTS = [
    ("scans", SCANS, {}),
    ("bag", FIXTURES / "recordings" / "bag" / "lz4.bag", {}),
    ("mcap", FIXTURES / "recordings" / "mcap" / "cdr-zstd.mcap", {}),
    ("ros2-db3", FIXTURES / "recordings" / "ros2-db3", {}),
    ("ros2-mcap", FIXTURES / "recordings" / "ros2-mcap", {}),
    ("pcap", FIXTURES / "packets" / "hdl32e-drive.pcap", {}),
    ("ouster", FIXTURES / "packets" / "ouster-os1-128-lowdata.pcap", {}),
]


def register_all(source, **pipeline):
    p = slamesh.Pipeline(**pipeline)
    statuses = []
    for frame in source:
        try:
            r = p.register(frame.points, frame.times, stamp=frame.stamp, imu=frame.imu)
            statuses.append(r.status)
        except slamesh.FrameError:
            statuses.append("skipped")
    return p, statuses


def same_files(a, b, names):
    return {n: filecmp.cmp(a / n, b / n, shallow=False) for n in names}


@pytest.mark.parametrize("name,path,flags", INPUTS, ids=[i[0] for i in INPUTS])
def test_every_input_gives_the_commands_poses_and_mesh_byte_for_byte(
    name, path, flags, tmp_path, command
):
    # The IMU's readings (the recordings' /imu topic, the Ouster's IMU packets) go with their
    # frames from `slamesh.read` to `register` as the command's run hands them on.
    command(["run", path, "--out", tmp_path / "cmd", "--threads", "2", "--no-picture"], tmp_path)
    p, statuses = register_all(slamesh.read(path, **flags), threads=2)
    assert len(statuses) >= 2, statuses
    p.save_trajectories(tmp_path / "py")
    p.save_mesh(tmp_path / "py" / "mesh.ply")
    names = ["poses_kitti.txt", "poses_tum.txt", "mesh.ply"]
    assert same_files(tmp_path / "cmd", tmp_path / "py", names) == {n: True for n in names}


# Every sequence with the KITTI preset on two threads, and the preset that fits itself to the
# first scan on one thread (serial) on two of them.
KITTI_RUNS = [(s, "kitti", 2) for s in ["00", "01", "02", "03", "04"]] + [
    ("00", "default", 1),
    ("01", "default", 1),
]


@pytest.mark.parametrize("seq,preset,threads", KITTI_RUNS, ids=["-".join(map(str, r)) for r in KITTI_RUNS])
def test_kitti_mini_poses_equal_the_commands_byte_for_byte(seq, preset, threads, tmp_path, command):
    folder = data_folder() / "kitti-mini" / seq
    assert folder.is_dir(), f"{folder} is missing"
    command(
        ["run", folder, "--out", tmp_path / "cmd", "--preset", preset, "--threads", threads,
         "--no-picture"],
        tmp_path,
    )
    p, statuses = register_all(slamesh.read(folder), preset=preset, threads=threads)
    assert "skipped" not in statuses
    p.save_trajectories(tmp_path / "py")
    for n in ["poses_kitti.txt", "poses_tum.txt"]:
        assert filecmp.cmp(tmp_path / "cmd" / n, tmp_path / "py" / n, shallow=False), n
    # The arrays are the poses the files print (KITTI's rows to 10 significant digits).
    written = np.loadtxt(tmp_path / "cmd" / "poses_kitti.txt").reshape(-1, 3, 4)
    assert p.poses().shape == (len(written), 4, 4)
    np.testing.assert_allclose(p.poses()[:, :3, :], written, rtol=1e-8, atol=1e-8)
    np.testing.assert_array_equal(p.poses()[:, 3, :], np.tile([0.0, 0.0, 0.0, 1.0], (len(written), 1)))


def first_scans():
    return [f.points for f in slamesh.read(SCANS)]


@pytest.mark.parametrize(
    "bad,message",
    [
        (np.zeros((5, 4)), r"an \(N, 3\) array is needed, this one has shape \(5, 4\)"),
        (np.zeros(9), r"an \(N, 3\) array is needed, this one has shape \(9,\)"),
        (np.zeros((0, 3)), "the array is empty"),
        (np.full((300, 3), np.nan), "300 row\\(s\\) are not finite"),
        (np.array([["a", "b", "c"]]), "real numbers are needed"),
        ([[1.0, 2.0], [3.0]], "not an array of numbers|shape"),
    ],
    ids=["columns", "flat", "empty", "nan", "text", "ragged"],
)
def test_a_bad_array_raises_a_clear_error_and_the_pipeline_goes_on(bad, message):
    scans = first_scans()
    p = slamesh.Pipeline(preset="kitti")
    p.register(scans[0])
    with pytest.raises(ValueError, match=message):
        p.register(bad)
    r = p.register(scans[1])
    assert r.frame == 1 and r.status == "Converged", r
    assert p.poses().shape == (2, 4, 4)


def test_a_row_of_nan_is_named_and_float64_is_taken():
    scans = first_scans()
    p = slamesh.Pipeline(preset="kitti")
    bad = scans[0].astype(np.float64)
    bad[7] = [np.inf, 0.0, 1.0]
    with pytest.raises(ValueError, match="the first is row 7"):
        p.register(bad)
    r = p.register(scans[0].astype(np.float64))
    assert r.status == "FirstScan" and r.pose.dtype == np.float64 and r.pose.shape == (4, 4)


def test_a_skipped_frame_raises_frame_error_with_the_commands_reason_and_is_counted():
    scans = first_scans()
    p = slamesh.Pipeline(preset="kitti")
    p.register(scans[0])
    with pytest.raises(slamesh.FrameError, match=r"frame 1: empty scan: none of 3 points usable"):
        p.register(np.zeros((3, 3), dtype=np.float32))
    r = p.register(scans[1], stamp=0.2)
    assert r.frame == 2 and r.stamp == 0.2
    assert list(p.frames()) == [0, 2]


def test_times_must_match_the_points():
    scans = first_scans()
    p = slamesh.Pipeline(preset="kitti")
    with pytest.raises(ValueError, match="times: one per point"):
        p.register(scans[0], times=np.zeros(3))
    assert p.register(scans[0], times=np.zeros(len(scans[0]))).status == "FirstScan"


def test_imu_readings_travel_with_their_frame_and_a_bad_array_is_refused():
    scans = first_scans()
    p = slamesh.Pipeline(preset="kitti")
    plain = slamesh.Pipeline(preset="kitti")
    for k, scan in enumerate(scans[:3]):
        # 20 readings at 200 Hz since the last frame: time, gyro x y z, accelerometer x y z.
        t = 0.1 * k - 0.1 + 0.005 * np.arange(1, 21)
        imu = np.column_stack([t, np.zeros((20, 5)), np.full(20, 9.81)])
        r = p.register(scan, stamp=0.1 * k, imu=imu)
        assert r.record["samples"] == 20, r.record
        q = plain.register(scan, stamp=0.1 * k)
        assert "samples" not in q.record and "imu" not in q.record
        # They give each frame after the first its prior (docs/design.md §1.19): a gyro that
        # reads no turn, as these first scans barely turn; the poses stay within 2 cm.
        assert r.record["imu"]["prior"] == (k > 0), r.record
        assert np.abs(r.pose[:3, 3] - q.pose[:3, 3]).max() < 0.02
    with pytest.raises(ValueError, match=r"imu: an \(M, 7\) array"):
        p.register(scans[2], stamp=0.3, imu=np.zeros((4, 6)))
    with pytest.raises(ValueError, match="imu: some values are not finite"):
        p.register(scans[2], stamp=0.3, imu=np.full((2, 7), np.nan))
    assert p.register(scans[2], stamp=0.3).frame == 3


def test_read_hands_each_frames_imu_readings():
    # The bag's /imu topic (make.py): a reading a microsecond before each of its 3 clouds,
    # both rates (0, 0, 9.81). A frame brings those up to a frame period past its stamp, the
    # first up to 0.4 s past it (the command's rule: up from the readings after a first scan
    # when none came before), each once; a folder of scans without a CSV brings none.
    frames = list(slamesh.read(FIXTURES / "recordings" / "bag" / "lz4.bag"))
    imu = np.concatenate([f.imu for f in frames if f.imu is not None])
    assert imu.shape == (3, 7) and imu.dtype == np.float64
    assert np.abs(imu[:, 0] - [f.stamp for f in frames]).max() < 1e-5
    assert (imu[:, 1:] == [0.0, 0.0, 9.81, 0.0, 0.0, 9.81]).all()
    assert frames[0].imu.shape == (3, 7)
    assert all(f.imu is None for f in frames[1:])
    assert all(f.imu is None for f in slamesh.read(SCANS))
    assert all(f.imu is None for f in slamesh.read(FIXTURES / "recordings" / "bag" / "lz4.bag", imu="off"))


def test_mesh_arrays_round_trip_through_save_mesh(tmp_path):
    p = slamesh.Pipeline(preset="kitti")
    for points in first_scans():
        p.register(points)
    m = p.mesh()
    counts = p.save_mesh(tmp_path / "m.ply")
    back = slamesh.read_mesh(tmp_path / "m.ply")
    assert counts == (len(m.vertices), len(m.faces)) and len(m.faces) > 1000
    for name in ["vertices", "faces", "normals", "variances"]:
        np.testing.assert_array_equal(getattr(m, name), getattr(back, name), err_msg=name)
    assert m.vertices.dtype == np.float32 and m.faces.dtype == np.uint32
    assert m.faces.max() < len(m.vertices)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-5)
    assert (m.variances > 0).all()


def test_settings_are_checked_and_a_bad_file_is_named(tmp_path):
    with pytest.raises(ValueError, match='preset: "indoor" is not one of default, quick, fast, kitti, meshing, town'):
        slamesh.Pipeline(preset="indoor")
    with pytest.raises(ValueError, match='capacity: "128" is not one of'):
        slamesh.Pipeline(capacity="128")
    bad = tmp_path / "bad.toml"
    bad.write_text("[grid]\ncell_size_m = -1\n")
    with pytest.raises(slamesh.SlameshError, match="bad.toml"):
        slamesh.Pipeline(config=bad)
    with pytest.raises(slamesh.SlameshError, match="no_such_folder"):
        slamesh.read(tmp_path / "no_such_folder")
    with pytest.raises(slamesh.SlameshError, match="no_such_folder"):
        slamesh.run(tmp_path / "no_such_folder", out=tmp_path / "out")


def test_a_capture_too_short_for_a_turn_is_refused_with_the_commands_message():
    short = FIXTURES / "packets" / "hdl32e-street.pcapng"
    with pytest.raises(slamesh.SlameshError, match="84 HDL-32E data packets, but not one whole turn"):
        slamesh.read(short)


def test_the_gil_is_released_while_a_frame_registers():
    scans = first_scans()
    big = np.concatenate([s + np.float32(0.001 * k) for k, s in enumerate(scans * 8)])
    p = slamesh.Pipeline(preset="kitti", threads=1)
    p.register(big)
    ticks, stop = [0], threading.Event()

    def count():
        while not stop.is_set():
            ticks[0] += 1

    t = threading.Thread(target=count)
    t.start()
    time.sleep(0.01)
    before = ticks[0]
    started = time.perf_counter()
    p.register(big)
    took = time.perf_counter() - started
    during = ticks[0] - before
    stop.set()
    t.join()
    # Holding the GIL, the register call would leave the counting thread no turn at all.
    assert during > 1000, (during, took)


def test_run_writes_what_the_command_writes(tmp_path, command):
    report = slamesh.run(SCANS, out=tmp_path / "py", threads=2, no_picture=True)
    command(["run", SCANS, "--out", tmp_path / "cmd", "--threads", "2", "--no-picture"], tmp_path)
    assert report["summary"]["used"] == 3
    assert same_files(tmp_path / "cmd", tmp_path / "py", ["poses_kitti.txt", "mesh.ply"]) == {
        "poses_kitti.txt": True,
        "mesh.ply": True,
    }


def test_the_readmes_python_runs(tmp_path, monkeypatch):
    from conftest import ROOT

    data = data_folder()
    text = (ROOT / "README.md").read_text()
    block = text.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(block.replace("../shared/data", str(data)), scope)
    assert scope["r"].status == "Converged" and scope["m"].faces.shape[1] == 3
    assert scope["report"]["summary"]["used"] == 10
    assert (tmp_path / "map.ply").is_file() and (tmp_path / "out" / "poses_kitti.txt").is_file()


def test_a_map_saved_by_run_is_localized_in(tmp_path):
    slamesh.run(SCANS, out=tmp_path / "a", save_map=tmp_path / "m.slamesh", no_picture=True)
    report = slamesh.localize(SCANS, map=tmp_path / "m.slamesh", out=tmp_path / "b", no_picture=True)
    counts = dict(report["summary"]["health"]["counts"])
    assert counts.get("Relocalized") == 1 and report["summary"]["used"] == 3, counts
