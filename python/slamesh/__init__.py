"""slamesh: real-time LiDAR localization and meshing, from Python.

The pipeline, frame by frame::

    import numpy as np, slamesh
    p = slamesh.Pipeline(preset="kitti")
    for frame in slamesh.read("kitti/00"):
        r = p.register(frame.points, frame.times, stamp=frame.stamp)
        print(r.status, r.pose[:3, 3])
    vertices, faces = p.mesh().vertices, p.mesh().faces
    p.save_mesh("map.ply")

or a whole run, exactly as the command does it (``slamesh run``)::

    report = slamesh.run("kitti/00", out="out00", preset="kitti")

Frames go through the command's own run, so the poses are the command's to the bit. The GIL
is released while slamesh works. Errors are exceptions with the command's messages:
``SlameshError`` for a file, an input or a setting; ``FrameError`` (a ``SlameshError``) for a
frame that was skipped, after which the pipeline goes on; ``ValueError`` for an array that is
not an (N, 3) array of finite numbers.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, Iterator, Optional, Union

import numpy as np

from . import _slamesh
from ._slamesh import FrameError, SlameshError

__version__: str = _slamesh.__version__
PRESETS: list[str] = list(_slamesh.PRESETS)

PathLike = Union[str, "os.PathLike[str]"]

__all__ = [
    "Frame",
    "FrameError",
    "Mesh",
    "PRESETS",
    "Pipeline",
    "Reader",
    "Registration",
    "SlameshError",
    "command",
    "localize",
    "read",
    "read_mesh",
    "run",
]


@dataclass(frozen=True)
class Registration:
    """What :meth:`Pipeline.register` made of one frame."""

    pose: np.ndarray
    """The sensor's pose in the map (the first frame's sensor frame): a 4 x 4 float64 matrix."""
    status: str
    """``Converged``, ``Recovered``, ``Degenerate``, ``Relocalized``, ... (see the README)."""
    reason: Optional[str]
    """Why the status is not a plain success, in words; ``None`` when it is."""
    frame: int
    """The frame's index (from 0, counting every frame given)."""
    stamp: float
    """The frame's time (seconds)."""
    timings: dict[str, float]
    """Milliseconds per stage (``read``, ``filter``, ``register``, ..., ``total``)."""
    record: dict[str, Any] = field(repr=False)
    """Everything ``report.json`` says of the frame."""


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh as arrays."""

    vertices: np.ndarray
    """(V, 3) float32 positions."""
    faces: np.ndarray
    """(F, 3) uint32 vertex indices, counter-clockwise seen from the normal's side."""
    normals: np.ndarray
    """(V, 3) float32 unit normals ((0, 3) when the file had none)."""
    variances: np.ndarray
    """(V,) float32: each vertex's variance from the Gaussian process ((0,) when none)."""


@dataclass(frozen=True)
class Frame:
    """One frame of an input (see :func:`read`)."""

    index: int
    points: np.ndarray
    """(N, 3) float32 points in the sensor frame."""
    times: Optional[np.ndarray]
    """(N,) float32 seconds of each point from ``stamp``, when the input records them."""
    stamp: float
    """Seconds."""
    label: str
    """What the command calls it in messages (its file)."""
    imu: Optional[np.ndarray] = None
    """(M, 7) float64 IMU readings that came with it (``time, gyro x, y, z, accelerometer x,
    y, z``, as :meth:`Pipeline.register` takes them), ``None`` when none did: a recording's
    ``sensor_msgs/Imu`` topic, a folder's ``imu0/data.csv``, an Ouster's IMU packets. Frames
    read in order hand each reading once."""


def _points(points: Any) -> np.ndarray:
    """``points`` as a C-contiguous (N, 3) float32 array, or ``ValueError`` saying why not."""
    try:
        a = np.asarray(points)
    except Exception as e:  # a ragged list, an object numpy cannot read
        raise ValueError(f"points: not an array of numbers: {e}") from None
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"points: an (N, 3) array is needed, this one has shape {a.shape}")
    if a.shape[0] == 0:
        raise ValueError("points: the array is empty")
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise ValueError(f"points: real numbers are needed, this array holds {a.dtype}")
    a = np.ascontiguousarray(a, dtype=np.float32)
    bad = ~np.isfinite(a).all(axis=1)
    if bad.any():
        rows = np.flatnonzero(bad)
        raise ValueError(
            f"points: {rows.size} row(s) are not finite (NaN or infinite, once as float32), "
            f"the first is row {rows[0]}: {a[rows[0]].tolist()}; drop them "
            f"(points[np.isfinite(points).all(axis=1)])"
        )
    return a


def _times(times: Any, n: int) -> Optional[np.ndarray]:
    if times is None:
        return None
    t = np.ascontiguousarray(np.asarray(times), dtype=np.float32)
    if t.ndim != 1 or t.shape[0] != n:
        raise ValueError(f"times: one per point is needed ({n},), this array has shape {t.shape}")
    if not np.isfinite(t).all():
        raise ValueError("times: some are not finite")
    return t


def _imu(imu: Any) -> Optional[np.ndarray]:
    """``imu`` as a C-contiguous (M, 7) float64 array of finite numbers, or ``ValueError``."""
    if imu is None:
        return None
    a = np.ascontiguousarray(np.asarray(imu), dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 7:
        raise ValueError(
            "imu: an (M, 7) array is needed (time, gyro x y z, accelerometer x y z), "
            f"this one has shape {a.shape}"
        )
    if not np.isfinite(a).all():
        raise ValueError("imu: some values are not finite")
    return a


class Pipeline:
    """slamesh's pipeline: register frames one by one, get the poses and the mesh map.

    Parameters
    ----------
    preset:
        ``"default"`` (fits its cell size to the first frame's scale), ``"quick"``
        (``default`` with one reconstruction a scan less), ``"kitti"``, ``"fast"``,
        ``"meshing"`` or ``"town"``, as ``slamesh run --preset``.
    capacity:
        ``"auto"`` (the smallest class that holds the first frame's points within range),
        ``"tiny"``, ``"16"``, ``"32"`` or ``"64"``, as ``--capacity``.
    config:
        A TOML configuration file instead of a preset (``slamesh config`` prints one).
    threads:
        Reconstruction threads (0: one per core; 1: serial), as ``--threads``.
    deskew:
        Deskew frames given with per-point times, as ``--deskew auto``.
    """

    def __init__(
        self,
        preset: Optional[str] = None,
        capacity: str = "auto",
        config: Optional[PathLike] = None,
        threads: int = 0,
        deskew: bool = True,
    ) -> None:
        if preset is None and config is None:
            preset = "default"
        self._engine = _slamesh.Engine(
            preset=preset,
            config=None if config is None else os.fspath(config),
            capacity=str(capacity),
            threads=int(threads),
            deskew=bool(deskew),
        )
        self._next_stamp = 0.0

    def register(
        self,
        points: Any,
        times: Any = None,
        stamp: Optional[float] = None,
        imu: Any = None,
    ) -> Registration:
        """Registers one scan and fuses it into the map.

        ``points``: (N, 3) float32 or float64 sensor-frame points (float64 is rounded to
        float32, as slamesh stores points). ``times``: optional (N,) seconds of each point from
        ``stamp``, for deskewing. ``stamp``: the frame's time in seconds (default: 0.1 s after
        the previous frame's, a 10 Hz sensor). ``imu``: optional IMU readings since the last
        frame, an (M, 7) array of rows ``time, gyro x, y, z (rad/s), accelerometer x, y, z
        (m/s^2)``, as :attr:`Frame.imu` holds them; they deskew the scan and start its
        registration as the command's IMU does (docs/design.md §1.19; the IMU's place on the
        LiDAR is the configuration's ``[imu]``), and ``record["imu"]`` says what they did.

        Raises ``ValueError`` for a bad array (the frame is not counted) and ``FrameError``
        when the pipeline skipped the frame (counted, as the command counts it); either way the
        pipeline goes on with the next frame.
        """
        pts = _points(points)
        t = _times(times, pts.shape[0])
        readings = _imu(imu)
        if stamp is None:
            stamp = self._next_stamp
        stamp = float(stamp)
        self._next_stamp = stamp + 0.1
        record, pose = self._engine.register(pts, t, stamp, readings)
        rec = json.loads(record)
        return Registration(
            pose=pose,
            status=rec["status"],
            reason=rec.get("reason"),
            frame=rec["frame"],
            stamp=rec["stamp"],
            timings=dict(rec["ms"]),
            record=rec,
        )

    def poses(self) -> np.ndarray:
        """The used frames' poses so far, (N, 4, 4) float64."""
        return self._engine.poses()[2]

    def stamps(self) -> np.ndarray:
        """The used frames' stamps, (N,) float64 seconds."""
        return self._engine.poses()[1]

    def frames(self) -> np.ndarray:
        """The used frames' indices, (N,) uint64 (a skipped frame's index is missing)."""
        return self._engine.poses()[0]

    def save_trajectories(self, folder: PathLike) -> None:
        """Writes ``poses_kitti.txt`` and ``poses_tum.txt`` into ``folder``, byte for byte as
        ``slamesh run`` writes them."""
        self._engine.save_trajectories(os.fspath(folder))

    def mesh(self) -> Mesh:
        """The map's mesh: what :meth:`save_mesh` writes."""
        return Mesh(*self._engine.mesh())

    def save_mesh(self, path: PathLike) -> tuple[int, int]:
        """Writes the map's mesh as ``slamesh run`` writes ``mesh.ply`` (binary PLY with
        normals and variances); returns its vertex and triangle counts."""
        return self._engine.save_mesh(os.fspath(path))

    @property
    def capacity(self) -> Optional[str]:
        """The capacity class in use; ``None`` before the first frame."""
        return self._engine.capacity

    @property
    def config_toml(self) -> str:
        """The configuration in use, as the file ``slamesh config`` prints."""
        return self._engine.config_toml


class Reader:
    """The frames of an input, read as ``slamesh run`` reads them (see :func:`read`).

    Iterating yields each :class:`Frame`; a frame that cannot be read raises ``FrameError``
    from ``next()``, and the next ``next()`` goes on with the frame after it.
    """

    def __init__(self, path: PathLike, **options: Any) -> None:
        args = {k: (os.fspath(v) if isinstance(v, os.PathLike) else v) for k, v in options.items()}
        self._source = _slamesh.Source(os.fspath(path), **args)
        self._next = 0

    def __len__(self) -> int:
        """Frames known now (a live input's grow)."""
        return self._source.frames()

    def __getitem__(self, i: int) -> Frame:
        if i < 0:
            i += len(self)
        points, times, stamp, label, imu = self._source.read(i)
        return Frame(i, points, times, stamp, label, imu)

    def __iter__(self) -> Iterator[Frame]:
        return self

    def __next__(self) -> Frame:
        i = self._next
        if not self._source.has(i):
            raise StopIteration
        self._next = i + 1
        return self[i]

    def describe(self) -> str:
        """What was opened, as the command's log says it."""
        return self._source.describe()

    def close(self) -> None:
        """Ends a live input."""
        self._source.close()


def read(
    path: PathLike,
    topic: Optional[str] = None,
    bin_fields: str = "x,y,z,i",
    sensor: Optional[str] = None,
    metadata: Optional[PathLike] = None,
    calibration: Optional[PathLike] = None,
    cut_azimuth: Optional[float] = None,
    idle_timeout: Optional[float] = None,
    imu: Optional[PathLike] = None,
    imu_topic: Optional[str] = None,
) -> Reader:
    """Opens what ``slamesh run`` reads: a folder of scans (.bin, .pcd, .ply) or a KITTI
    sequence, one scan file, a recording (ROS 1 bag, MCAP, ROS 2 bag folder), a Velodyne or
    Ouster packet capture (.pcap, .pcapng) or ``udp://HOST:PORT`` for live packets. The
    arguments are the command's flags of the same names (``slamesh run --help``); each
    :class:`Frame` brings the IMU's readings that come with it (``imu="off"`` ignores them)."""
    return Reader(
        path,
        topic=topic,
        bin_fields=bin_fields,
        sensor=sensor,
        metadata=metadata,
        calibration=calibration,
        cut_azimuth=cut_azimuth,
        idle_timeout=idle_timeout,
        imu=imu,
        imu_topic=imu_topic,
    )


def read_mesh(path: PathLike) -> Mesh:
    """A PLY mesh's arrays (normals and variances when the file has them)."""
    return Mesh(*_slamesh.read_mesh(os.fspath(path)))


def command(*args: Any) -> None:
    """Runs ``slamesh ARGS...`` in this process (``command("eval", "--estimate", ...)``);
    raises ``SlameshError`` with the command's message when it fails."""
    _slamesh.command([os.fspath(a) if isinstance(a, os.PathLike) else str(a) for a in args])


def _flags(options: dict[str, Any]) -> list[Any]:
    """Keyword arguments as the command's flags: ``save_map=p`` is ``--save-map p``, ``True``
    a bare flag, ``None`` and ``False`` none."""
    out: list[Any] = []
    for key, value in options.items():
        if value is None or value is False:
            continue
        out.append("--" + key.replace("_", "-"))
        if value is not True:
            out.append(value)
    return out


def _report_of(subcommand: str, input: PathLike, out: PathLike, quiet: bool, options: dict) -> dict:
    """Runs ``slamesh SUBCOMMAND INPUT --out OUT [-q] FLAGS`` and reads its ``report.json``."""
    command(subcommand, input, "--out", out, *(["-q"] if quiet else []), *_flags(options))
    with open(os.path.join(os.fspath(out), "report.json")) as f:
        return json.load(f)


def run(input: PathLike, out: PathLike, quiet: bool = True, **options: Any) -> dict[str, Any]:
    """``slamesh run INPUT --out OUT`` with ``options`` as its flags (``preset="kitti"`` is
    ``--preset kitti``, ``save_map="m.slamesh"`` is ``--save-map m.slamesh``, ``obj=True`` is
    ``--obj``), in this process; returns ``report.json``. The outputs are the command's, in
    ``out``."""
    return _report_of("run", input, out, quiet, options)


def localize(
    input: PathLike, map: PathLike, out: PathLike, quiet: bool = True, **options: Any
) -> dict[str, Any]:
    """``slamesh localize INPUT --map MAP --out OUT`` with ``options`` as flags; returns
    ``report.json``."""
    return _report_of("localize", input, out, quiet, {"map": map, **options})
