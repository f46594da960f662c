"""Trajectory files: the HDF5 (H5MD 1.1) writer and reader.

Layout (the "Trajectory file" contract of DESIGN.md)::

    /h5md                               version [1, 1]; author/name; creator/name, version
    /particles/bodies/box               dimension 2, boundary ["none", "none"]
    /particles/bodies/position          step (T,) int64, time (T,) float64 s, value (T,N,2) m
    /particles/bodies/orientation       value (T,N,2) = (cos θ, sin θ)
    /particles/bodies/angle             value (T,N) rad, unwrapped
    /particles/bodies/velocity          value (T,N,2) m s-1, centre of mass
    /particles/bodies/angular_velocity  value (T,N) rad s-1
    /particles/bodies/{name,type,mass,moment_of_inertia,center_of_mass}     (N,) / (N,2)
    /particles/bodies/shapes/{body,kind,radius,vertex_start,vertex_count,vertices}
    /observables/<name>                 step, time, value (T,) or (T,k)
    /parameters/rbsim/<key>             scalar utf-8 strings (scene, solver, engine, status, ...)

`step` and `time` are created once, under `position`, and hard-linked into every other
time series group (H5MD allows shared step and time datasets).

Durability: the file is written in four phases so that it can be opened at any moment
that matters. The constructor writes the static data and closes the file (a kill before
the first frame leaves a valid file with no frames). The first `append` reopens it,
creates every time-dependent dataset, and switches on SWMR (single writer, multiple
readers); from then on frames are appended by resizing and flushed at most every
`flush_seconds`, so a `kill -9` leaves a file that a SWMR reader opens with every frame
flushed so far. `close` writes the final status and closes the file cleanly. The status
and wall time are fixed-length string datasets created before SWMR starts, because new
objects (and variable-length data) cannot be written in SWMR mode; a file whose writer
is still running, or was killed, reads status "running".
"""

from __future__ import annotations

import difflib
import getpass
import json
import math
import os
import time as _time
from dataclasses import dataclass, field
from types import TracebackType

import h5py
import numpy as np

from ..scene.types import BODY_TYPES, SHAPE_KINDS

__all__ = [
    "BodyTable",
    "Trajectory",
    "TrajectoryWriter",
    "load_trajectory",
    "summarize",
]

H5MD_VERSION = (1, 1)
STATUS_RUNNING = "running"

# Per-body time series: name -> (components per body, unit). 0 components = (T,N).
BODY_SERIES: dict[str, tuple[int, str | None]] = {
    "position": (2, "m"),
    "orientation": (2, None),
    "angle": (0, "rad"),
    "velocity": (2, "m s-1"),
    "angular_velocity": (0, "rad s-1"),
}
# Units of the observables rbsim writes; other observable names are stored without a unit.
OBSERVABLE_UNITS = {
    "kinetic_energy": "J",
    "potential_energy": "J",
    "total_energy": "J",
    "linear_momentum": "kg m s-1",
    "angular_momentum": "kg m2 s-1",
}
# Keys of /parameters/rbsim that the writer owns.
RESERVED_PARAMETERS = ("status", "wall_time")

# Chunks of time-dependent datasets hold whole frames: CHUNK_MAX_FRAMES of them, or
# fewer so that a chunk stays under about CHUNK_TARGET_BYTES (at least one frame).
# Chunks are allocated whole, so a larger maximum bloats files of short, small runs.
CHUNK_TARGET_BYTES = 1 << 20
CHUNK_MAX_FRAMES = 64
# Per-dataset chunk cache of the writer, bytes. Must exceed one chunk, or every append
# writes straight through to the file.
CHUNK_CACHE_BYTES = 4 << 20
# Fixed byte lengths of the status and wall-time strings (writable in SWMR mode).
# Longer statuses are cut (at a character boundary).
STATUS_BYTES = 256
WALL_TIME_BYTES = 32

_STR = h5py.string_dtype("utf-8")


def _package_version() -> str:
    try:
        from rbsim import __version__  # type: ignore[attr-defined]
    except ImportError:
        return "0"
    return str(__version__)


def _author() -> str:
    try:
        return getpass.getuser()
    except Exception:  # no login name in some containers
        return "unknown"


# ---------------------------------------------------------------------------------------
# Static per-body data
# ---------------------------------------------------------------------------------------


@dataclass
class BodyTable:
    """Static per-body data of N bodies made of S shapes with V vertices in all.

    name: (N,) unique body names. type: (N,) "dynamic" | "static" | "kinematic".
    mass: (N,) kg, inf for static and kinematic bodies.
    moment_of_inertia: (N,) kg m², about the centre of mass; inf likewise.
    center_of_mass: (N,2) m, in the body frame (offset from the body origin).
    shape_body: (S,) int32, index of the body each shape belongs to.
    shape_kind: (S,) "circle" | "box" | "polygon" | "segment".
    shape_radius: (S,) m; circle radius, segment radius (capsule), 0 for polygons.
    shape_vertex_start, shape_vertex_count: (S,) int32, each shape's rows of
        shape_vertices (circle: its centre; segment: a, b; box/polygon: CCW corners).
    shape_vertices: (V,2) m, body frame.

    Array fields are converted to numpy arrays of the stated dtypes on construction.
    """

    name: list[str]
    type: list[str]
    mass: np.ndarray
    moment_of_inertia: np.ndarray
    center_of_mass: np.ndarray
    shape_body: np.ndarray
    shape_kind: list[str]
    shape_radius: np.ndarray
    shape_vertex_start: np.ndarray
    shape_vertex_count: np.ndarray
    shape_vertices: np.ndarray

    def __post_init__(self) -> None:
        self.name = [str(s) for s in self.name]
        self.type = [str(s) for s in self.type]
        self.shape_kind = [str(s) for s in self.shape_kind]
        self.mass = np.asarray(self.mass, dtype=np.float64).reshape(-1)
        self.moment_of_inertia = np.asarray(self.moment_of_inertia, dtype=np.float64).reshape(-1)
        self.center_of_mass = np.asarray(self.center_of_mass, dtype=np.float64).reshape(-1, 2)
        self.shape_body = np.asarray(self.shape_body, dtype=np.int32).reshape(-1)
        self.shape_radius = np.asarray(self.shape_radius, dtype=np.float64).reshape(-1)
        self.shape_vertex_start = np.asarray(self.shape_vertex_start, dtype=np.int32).reshape(-1)
        self.shape_vertex_count = np.asarray(self.shape_vertex_count, dtype=np.int32).reshape(-1)
        self.shape_vertices = np.asarray(self.shape_vertices, dtype=np.float64).reshape(-1, 2)
        self._check()

    def __len__(self) -> int:
        return len(self.name)

    def _check(self) -> None:
        n, s, v = len(self.name), len(self.shape_kind), len(self.shape_vertices)
        for field_name, length, expected in (
            ("type", len(self.type), n),
            ("mass", len(self.mass), n),
            ("moment_of_inertia", len(self.moment_of_inertia), n),
            ("center_of_mass", len(self.center_of_mass), n),
            ("shape_body", len(self.shape_body), s),
            ("shape_radius", len(self.shape_radius), s),
            ("shape_vertex_start", len(self.shape_vertex_start), s),
            ("shape_vertex_count", len(self.shape_vertex_count), s),
        ):
            if length != expected:
                raise ValueError(f"BodyTable.{field_name} has {length} rows, expected {expected}")
        bad_types = sorted(set(self.type) - set(BODY_TYPES))
        if bad_types:
            raise ValueError(f"BodyTable.type: unknown {bad_types}, expected one of {BODY_TYPES}")
        bad_kinds = sorted(set(self.shape_kind) - set(SHAPE_KINDS))
        if bad_kinds:
            raise ValueError(
                f"BodyTable.shape_kind: unknown {bad_kinds}, expected one of {SHAPE_KINDS}"
            )
        if s and (self.shape_body.min() < 0 or self.shape_body.max() >= n):
            raise ValueError(f"BodyTable.shape_body: indices must lie in [0, {n})")
        end = self.shape_vertex_start.astype(np.int64) + self.shape_vertex_count
        if s and (self.shape_vertex_start.min() < 0 or end.max() > v):
            raise ValueError(f"BodyTable.shape_vertex_start/count: rows must lie in [0, {v})")


def _write_body_table(group: h5py.Group, bodies: BodyTable) -> None:
    group.create_dataset("name", data=np.array(bodies.name, dtype=object), dtype=_STR)
    group.create_dataset("type", data=np.array(bodies.type, dtype=object), dtype=_STR)
    group.create_dataset("mass", data=bodies.mass).attrs["unit"] = "kg"
    group.create_dataset("moment_of_inertia", data=bodies.moment_of_inertia).attrs["unit"] = "kg m2"
    group.create_dataset("center_of_mass", data=bodies.center_of_mass).attrs["unit"] = "m"
    shapes = group.create_group("shapes")
    shapes.create_dataset("body", data=bodies.shape_body)
    shapes.create_dataset("kind", data=np.array(bodies.shape_kind, dtype=object), dtype=_STR)
    shapes.create_dataset("radius", data=bodies.shape_radius).attrs["unit"] = "m"
    shapes.create_dataset("vertex_start", data=bodies.shape_vertex_start)
    shapes.create_dataset("vertex_count", data=bodies.shape_vertex_count)
    shapes.create_dataset("vertices", data=bodies.shape_vertices).attrs["unit"] = "m"


def _read_strings(dataset: h5py.Dataset) -> list[str]:
    return [str(s) for s in dataset.asstr()[()]]


def read_body_table(group: h5py.Group) -> BodyTable:
    """The per-body table of an open file's /particles/bodies group."""
    shapes = group["shapes"]
    return BodyTable(
        name=_read_strings(group["name"]),
        type=_read_strings(group["type"]),
        mass=group["mass"][()],
        moment_of_inertia=group["moment_of_inertia"][()],
        center_of_mass=group["center_of_mass"][()],
        shape_body=shapes["body"][()],
        shape_kind=_read_strings(shapes["kind"]),
        shape_radius=shapes["radius"][()],
        shape_vertex_start=shapes["vertex_start"][()],
        shape_vertex_count=shapes["vertex_count"][()],
        shape_vertices=shapes["vertices"][()],
    )


# ---------------------------------------------------------------------------------------
# Writer
# ---------------------------------------------------------------------------------------


def _chunk_frames(frame_shape: tuple[int, ...], itemsize: int) -> int:
    """Whole frames per chunk: about CHUNK_TARGET_BYTES, within [1, CHUNK_MAX_FRAMES]."""
    frame_bytes = max(1, math.prod(frame_shape)) * itemsize
    return max(1, min(CHUNK_MAX_FRAMES, CHUNK_TARGET_BYTES // frame_bytes))


def _create_series(
    group: h5py.Group, name: str, frame_shape: tuple[int, ...], dtype: type, unit: str | None
) -> h5py.Dataset:
    """An empty (0, *frame_shape) dataset, chunked and resizable along T, uncompressed.
    Unwritten frames read as fill values: -1 for integers, NaN for floats."""
    dtype = np.dtype(dtype)
    # A chunk dimension must be >= 1 even for zero bodies.
    chunks = (_chunk_frames(frame_shape, dtype.itemsize), *(max(1, d) for d in frame_shape))
    fill = -1 if dtype.kind in "iu" else np.nan
    ds = group.create_dataset(
        name,
        shape=(0, *frame_shape),
        maxshape=(None, *frame_shape),
        chunks=chunks,
        dtype=dtype,
        fillvalue=fill,
    )
    if unit is not None:
        ds.attrs["unit"] = unit
    return ds


class _Series:
    """A dataset that grows along T, with its frame shape and low-level handles kept so
    that an append is two HDF5 calls (high-level h5py indexing costs ~50 µs a call,
    more than writing a frame of thousands of bodies)."""

    def __init__(self, dataset: h5py.Dataset) -> None:
        self.name = dataset.name
        self.dsid = dataset.id
        self.dtype = dataset.dtype
        self.frame: tuple[int, ...] = dataset.shape[1:]
        self.empty = math.prod(self.frame) == 0
        self.integral = self.dtype.kind in "iu" and self.name.startswith("/observables/")
        self.origin = (0,) * len(self.frame)
        self.count = (1, *self.frame)
        self.mspace = h5py.h5s.create_simple(self.count)

    def resize(self, frames: int) -> None:
        self.dsid.set_extent((frames, *self.frame))

    def write(self, t: int, value: object) -> None:
        """Write frame t (already checked to have shape self.frame)."""
        if self.empty:
            return
        arr = np.ascontiguousarray(value, dtype=self.dtype)
        if self.integral and np.any(arr != value):
            raise ValueError(f"{self.name}: {value!r} is not an integer, as in the first frame")
        fspace = self.dsid.get_space()
        fspace.select_hyperslab((t, *self.origin), self.count)
        self.dsid.write(self.mspace, fspace, arr)


class TrajectoryWriter:
    """Writes an rbsim trajectory (H5MD 1.1) frame by frame.

    path: the .h5 file to create (overwritten if it exists).
    bodies: static per-body data; fixes N, the number of bodies in every frame.
    parameters: strings stored under /parameters/rbsim (e.g. "scene" YAML text,
        "resolved_scene" and "solver" JSON, "rbsim_version"). "engine" is added from
        `engine`; "status" and "wall_time" are written by the writer.
    engine: "rbsim" or "pymunk", the engine that computed the frames.
    flush_seconds: the longest time, s, between flushes to disk; a killed writer loses
        at most the frames appended in the last `flush_seconds`. 0 flushes every frame.

    Use as a context manager, or call `close`. `frames_written` counts appended frames,
    `frames_flushed` those flushed to disk.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        bodies: BodyTable,
        parameters: dict[str, str],
        engine: str = "rbsim",
        flush_seconds: float = 1.0,
    ) -> None:
        params = {str(k): v for k, v in parameters.items()}
        for key, value in params.items():
            if not isinstance(value, str):
                raise TypeError(f"parameter {key!r} must be a str, got {type(value).__name__}")
        reserved = sorted(set(params) & set(RESERVED_PARAMETERS))
        if reserved:
            raise ValueError(f"parameters {reserved} are written by TrajectoryWriter.close")
        if params.setdefault("engine", engine) != engine:
            raise ValueError(f"parameters['engine']={params['engine']!r} but engine={engine!r}")
        if flush_seconds < 0:
            raise ValueError(f"flush_seconds must be >= 0, got {flush_seconds}")

        self.path = os.fspath(path)
        self.bodies = bodies
        self.engine = engine
        self.flush_seconds = float(flush_seconds)
        self.frames_written = 0
        self.frames_flushed = 0
        self._n = len(bodies)
        self._file: h5py.File | None = None
        self._closed = False
        self._started = _time.perf_counter()
        self._last_flush = _time.monotonic()
        self._series: list[_Series] = []  # every dataset that grows along T, written in order
        self._observable_names: tuple[str, ...] = ()

        # Phase 1: static data, then close, so that the file is valid before frame 0.
        with h5py.File(self.path, "w", libver="latest") as f:
            h5md = f.create_group("h5md")
            h5md.attrs["version"] = np.array(H5MD_VERSION, dtype=np.int32)
            h5md.create_group("author").attrs["name"] = _author()
            creator = h5md.create_group("creator")
            creator.attrs["name"] = "rbsim"
            creator.attrs["version"] = _package_version()
            group = f.create_group("particles/bodies")
            box = group.create_group("box")
            box.attrs["dimension"] = np.int32(2)
            box.attrs["boundary"] = np.array(["none", "none"], dtype=_STR)
            _write_body_table(group, bodies)
            f.create_group("observables")
            rb = f.create_group("parameters/rbsim")
            for key, value in params.items():
                rb.create_dataset(key, data=value, dtype=_STR)
            # Fixed-length strings: the only kind SWMR mode lets us overwrite at close.
            rb.create_dataset("status", data=STATUS_RUNNING.encode(), dtype=_fixed(STATUS_BYTES))
            rb.create_dataset("wall_time", data=b"", dtype=_fixed(WALL_TIME_BYTES))

    def __enter__(self) -> TrajectoryWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close(status="complete")
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close(status="interrupted")
        else:
            self.close(status="failed")

    def _open_for_frames(self, observables: dict[str, float | np.ndarray]) -> None:
        """Phase 2: reopen, create every time-dependent dataset, and (on the caller's
        side) switch on SWMR. Observables get the names, dtypes and shapes of the first
        frame's values: integers -> int64 (counts; not the energies and momenta, which are
        float64 even when the first frame gives 0), everything else float64."""
        arrays = {name: np.asarray(value) for name, value in observables.items()}
        for name, arr in arrays.items():
            if arr.ndim > 1:
                raise ValueError(f"observable {name!r} must be a scalar or 1-D, got {arr.shape}")
        f = h5py.File(self.path, "r+", libver="latest", rdcc_nbytes=CHUNK_CACHE_BYTES)
        self._file = f
        bodies = f["particles/bodies"]
        shared: tuple[h5py.Dataset, h5py.Dataset] | None = None
        for name, (components, unit) in BODY_SERIES.items():
            group = bodies.create_group(name)
            if shared is None:
                shared = (
                    _create_series(group, "step", (), np.int64, None),
                    _create_series(group, "time", (), np.float64, "s"),
                )
                self._series += [_Series(ds) for ds in shared]
            else:
                group["step"], group["time"] = shared  # hard links
            frame = (self._n, components) if components else (self._n,)
            self._series.append(_Series(_create_series(group, "value", frame, np.float64, unit)))
        assert shared is not None
        obs_group = f["observables"]
        for name, arr in arrays.items():
            integral = arr.dtype.kind in "iub" and name not in OBSERVABLE_UNITS
            dtype = np.int64 if integral else np.float64
            group = obs_group.create_group(name)
            group["step"], group["time"] = shared
            ds = _create_series(group, "value", arr.shape, dtype, OBSERVABLE_UNITS.get(name))
            self._series.append(_Series(ds))
        self._observable_names = tuple(observables)
        f.flush()

    def append(
        self,
        step: int,
        time: float,
        position: np.ndarray,
        orientation: np.ndarray,
        angle: np.ndarray,
        velocity: np.ndarray,
        angular_velocity: np.ndarray,
        observables: dict[str, float | np.ndarray],
    ) -> None:
        """Append one frame and flush if `flush_seconds` have passed since the last flush.

        step: step number; time: s. position (N,2) m, body origin; orientation (N,2)
        (cos θ, sin θ); angle (N,) rad, unwrapped; velocity (N,2) m/s of the centre of
        mass; angular_velocity (N,) rad/s. observables: name -> scalar or (k,) array
        (energies J, linear momentum kg m/s, angular momentum kg m²/s, contact count);
        the first frame fixes the names, later frames must give the same names.
        """
        if self._closed:
            raise ValueError(f"append to a closed trajectory ({self.path})")
        if self._file is None:
            self._open_for_frames(observables)
            self._file.swmr_mode = True  # type: ignore[union-attr]
        elif observables.keys() != set(self._observable_names):
            missing = sorted(set(self._observable_names) - observables.keys())
            extra = sorted(observables.keys() - set(self._observable_names))
            raise ValueError(
                f"observables must be those of the first frame: missing {missing}, "
                f"unexpected {extra}"
            )
        values = [step, time, position, orientation, angle, velocity, angular_velocity]
        values += [observables[name] for name in self._observable_names]
        t = self.frames_written
        for series, value in zip(self._series, values, strict=True):
            if np.shape(value) != series.frame:
                raise ValueError(
                    f"{series.name}: frame has shape {np.shape(value)}, expected {series.frame}"
                )
        # Resize everything first, then write: a kill between the two leaves fill
        # values (-1 steps) at the end, which load_trajectory trims.
        for series in self._series:
            series.resize(t + 1)
        for series, value in zip(self._series, values, strict=True):
            series.write(t, value)
        self.frames_written = t + 1
        if _time.monotonic() - self._last_flush >= self.flush_seconds:
            self.flush()

    def flush(self) -> None:
        """Write every appended frame to disk now (SWMR readers then see them)."""
        if self._file is not None and not self._closed:
            self._file.flush()
            self.frames_flushed = self.frames_written
        self._last_flush = _time.monotonic()

    def close(self, *, status: str = "complete", wall_time: float | None = None) -> None:
        """Flush, record `status` and `wall_time`, and close the file. Idempotent.

        status: "complete", "interrupted" (Ctrl-C, SIGTERM) or "failed", optionally with
            a detail after a colon ("failed: body 'ball' became non-finite at step 12");
            stored up to STATUS_BYTES bytes of UTF-8. Never raises on the text, so that
            closing in a `finally` cannot hide the error being handled.
        wall_time: s; by default the time since the writer was created.
        """
        if self._closed:
            return
        if wall_time is None:
            wall_time = _time.perf_counter() - self._started
        if self._file is None:  # no frame appended: create the empty series anyway
            self._open_for_frames({})
        f = self._file
        assert f is not None
        try:
            rb = f["parameters/rbsim"]
            text = str(status).encode("utf-8")[:STATUS_BYTES]
            rb["status"][()] = text.decode("utf-8", errors="ignore").encode("utf-8")
            rb["wall_time"][()] = repr(float(wall_time)).encode()
            f.flush()
            self.frames_flushed = self.frames_written
        finally:
            self._closed = True
            self._series = []
            f.close()


def _fixed(nbytes: int) -> np.dtype:
    return h5py.string_dtype("utf-8", nbytes)


# ---------------------------------------------------------------------------------------
# Reader
# ---------------------------------------------------------------------------------------


@dataclass
class Trajectory:
    """A trajectory file in memory: T frames of N bodies.

    step (T,) int64; time (T,) s; position (T,N,2) m, body origin; orientation (T,N,2)
    (cos θ, sin θ); angle (T,N) rad, unwrapped; velocity (T,N,2) m/s, centre of mass;
    angular_velocity (T,N) rad/s; observables name -> (T,) or (T,k) (energies J, linear
    momentum kg m/s, angular momentum kg m²/s, contact count); bodies: static data;
    parameters: /parameters/rbsim as strings; engine: "rbsim" or "pymunk"; status:
    "complete", "interrupted", "failed", or "running" (writer running or killed).
    """

    step: np.ndarray
    time: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    angle: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    observables: dict[str, np.ndarray]
    bodies: BodyTable
    parameters: dict[str, str]
    engine: str
    status: str
    _index: dict[str, int] | None = field(default=None, init=False, repr=False, compare=False)

    def body(self, name: str) -> int:
        """Index of the body called `name`; KeyError naming close matches otherwise."""
        if self._index is None:
            self._index = {n: i for i, n in enumerate(self.bodies.name)}
        try:
            return self._index[name]
        except KeyError:
            close = difflib.get_close_matches(name, self._index, n=3)
            hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
            raise KeyError(f"no body named {name!r}{hint}") from None


def open_for_reading(path: str | os.PathLike) -> h5py.File:
    """Open read-only; files whose writer is running or was killed need SWMR read mode."""
    try:
        return h5py.File(path, "r")
    except OSError as plain_error:
        try:
            return h5py.File(path, "r", swmr=True)
        except OSError:
            raise plain_error from None


def _series_groups(f: h5py.File) -> tuple[list[str], list[str]]:
    """Paths of the body and observable time series groups present in the file."""
    bodies = [f"particles/bodies/{n}" for n in BODY_SERIES if f"particles/bodies/{n}" in f]
    obs = [f"observables/{n}" for n in f["observables"]] if "observables" in f else []
    return bodies, obs


def frame_count(f: h5py.File, closed: bool) -> int:
    """Frames present in every time series: the shortest common length, less trailing
    frames whose step was never written (-1, the fill value). In a file that was not
    closed (writer running or killed) a trailing frame is also dropped when any series
    holds only fill values there (NaN, or -1 for integer observables): its extent
    reached the disk before its data did."""
    if "particles/bodies/position" not in f:
        return 0
    body_groups, obs_groups = _series_groups(f)
    values = [f[g]["value"] for g in body_groups + obs_groups]
    step, time = f["particles/bodies/position/step"], f["particles/bodies/position/time"]
    t = min(ds.shape[0] for ds in [*values, step, time])

    def unwritten(i: int) -> bool:
        if step[i] < 0:
            return True
        if closed:
            return False
        for ds in [time, *values]:
            frame = ds[i]
            if ds.dtype.kind == "f" and np.isnan(frame).all() and np.size(frame):
                return True
            if ds.dtype.kind in "iu" and (frame == -1).all() and np.size(frame):
                return True
        return False

    while t > 0 and unwritten(t - 1):
        t -= 1
    return t


def read_parameters(f: h5py.File) -> dict[str, str]:
    """/parameters/rbsim of an open file as text by name ({} when absent)."""
    params: dict[str, str] = {}
    group = f.get("parameters/rbsim")
    if group is None:
        return params
    for key, ds in group.items():
        value = ds[()]
        if isinstance(value, bytes):
            value = value.decode("utf-8").rstrip("\x00")
        params[key] = str(value)
    return params


def load_trajectory(path: str | os.PathLike) -> Trajectory:
    """Read a trajectory file written by TrajectoryWriter (closed normally, still being
    written, or left by a killed writer). Every series is cut to the frames present in
    all of them. Units as in `Trajectory`."""
    with open_for_reading(path) as f:
        bodies = read_body_table(f["particles/bodies"])
        n = len(bodies)
        params = read_parameters(f)
        t = frame_count(f, closed=params.get("status", STATUS_RUNNING) != STATUS_RUNNING)
        arrays: dict[str, np.ndarray] = {}
        for name, (components, _unit) in BODY_SERIES.items():
            key = f"particles/bodies/{name}/value"
            if t and key in f:
                arrays[name] = f[key][:t]
            else:
                arrays[name] = np.zeros((0, n, components) if components else (0, n))
        if t:
            step = f["particles/bodies/position/step"][:t]
            time = f["particles/bodies/position/time"][:t]
        else:
            step, time = np.zeros(0, dtype=np.int64), np.zeros(0)
        observables: dict[str, np.ndarray] = {}
        for group in _series_groups(f)[1]:
            observables[group.split("/", 1)[1]] = f[group]["value"][:t]
    return Trajectory(
        step=step,
        time=time,
        observables=observables,
        bodies=bodies,
        parameters=params,
        engine=params.get("engine", "unknown"),
        status=params.get("status", "unknown"),
        **arrays,
    )


# ---------------------------------------------------------------------------------------
# Summary (`rbsim info`)
# ---------------------------------------------------------------------------------------


def _human_bytes(n: int) -> str:
    size = float(n)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if size < 1024 or unit == "GiB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    raise AssertionError("unreachable")


def _json_or_none(text: str | None) -> object:
    if not text:
        return None
    try:
        return json.loads(text)
    except ValueError:
        return None


def scene_name(params: dict[str, str], path: str) -> str:
    """The run's scene name: from the resolved scene in `params`, else from `path`."""
    resolved = _json_or_none(params.get("resolved_scene"))
    if isinstance(resolved, dict) and resolved.get("name"):
        return str(resolved["name"])
    if params.get("scene"):
        import yaml

        try:
            scene = yaml.safe_load(params["scene"])
        except yaml.YAMLError:
            scene = None
        if isinstance(scene, dict) and scene.get("name"):
            return str(scene["name"])
    return f"(not recorded; file {os.path.basename(path)})"


def _format_value(value: np.ndarray) -> str:
    if value.ndim == 0:
        if value.dtype.kind in "iub":
            return str(int(value))
        return f"{float(value):.6g}"
    return "(" + ", ".join(f"{float(v):.6g}" for v in value) + ")"


def summarize(path: str | os.PathLike) -> str:
    """The text `rbsim info OUT.h5` prints: engine, status, scene name, bodies by type,
    frames, step and time range (s), dt (s), wall time (s), file size, observables at
    the first and last frame, and the solver parameters. Reads only what it prints."""
    path = os.fspath(path)
    with open_for_reading(path) as f:
        params = read_parameters(f)
        types = _read_strings(f["particles/bodies/type"])
        t = frame_count(f, closed=params.get("status", STATUS_RUNNING) != STATUS_RUNNING)
        step = time = np.zeros(0)
        if t:
            step = f["particles/bodies/position/step"][[0, t - 1] if t > 1 else [0]]
            time = f["particles/bodies/position/time"][[0, t - 1] if t > 1 else [0]]
        first_last: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
        for group in _series_groups(f)[1] if t else []:
            ds = f[group]["value"]
            unit = ds.attrs.get("unit", "")
            first_last[group.split("/", 1)[1]] = (ds[0], ds[t - 1], str(unit))
        creator_version = str(f["h5md/creator"].attrs.get("version", "?"))

    lines = [f"rbsim trajectory {path} ({_human_bytes(os.path.getsize(path))})"]
    version = params.get("rbsim_version", creator_version)
    lines.append(f"  engine     {params.get('engine', 'unknown')} (rbsim {version})")
    status = params.get("status", "unknown")
    if status == STATUS_RUNNING:
        status += " (not closed: the writer is still running or was killed)"
    lines.append(f"  status     {status}")
    lines.append(f"  scene      {scene_name(params, path)}")
    counts = ", ".join(f"{types.count(k)} {k}" for k in BODY_TYPES if types.count(k))
    lines.append(f"  bodies     {len(types)}" + (f" ({counts})" if counts else ""))
    if t:
        lines.append(
            f"  frames     {t} (steps {int(step[0])}..{int(step[-1])}, "
            f"time {float(time[0]):.6g}..{float(time[-1]):.6g} s)"
        )
    else:
        lines.append("  frames     0")
    dt = None
    if t > 1 and step[-1] != step[0]:
        dt = float(time[-1] - time[0]) / float(step[-1] - step[0])
    else:
        resolved = _json_or_none(params.get("resolved_scene"))
        if isinstance(resolved, dict) and isinstance(resolved.get("world"), dict):
            dt = resolved["world"].get("dt")
    lines.append(f"  dt         {dt:.6g} s" if isinstance(dt, float | int) else "  dt         ?")
    try:
        wall = float(params.get("wall_time", ""))
    except ValueError:
        lines.append("  wall time  ?")
    else:
        rate = ""
        if t > 1 and wall > 0:
            rate = f" ({float(step[-1] - step[0]) / wall:.4g} steps/s)"
        lines.append(f"  wall time  {wall:.3f} s{rate}")

    if first_last:
        if "kinetic_energy" in first_last and "potential_energy" in first_last:
            if "total_energy" not in first_last:
                ke, pe = first_last["kinetic_energy"], first_last["potential_energy"]
                first_last["total_energy"] = (ke[0] + pe[0], ke[1] + pe[1], ke[2])
        order = [
            "kinetic_energy",
            "potential_energy",
            "total_energy",
            "linear_momentum",
            "angular_momentum",
            "contact_count",
        ]
        names = [k for k in order if k in first_last]
        names += sorted(k for k in first_last if k not in order)
        rows = [("observable", "unit", "first frame", "last frame")]
        for name in names:
            first, last, unit = first_last[name]
            rows.append((name, unit, _format_value(first), _format_value(last)))
        widths = [max(len(row[i]) for row in rows) for i in range(4)]
        lines.append("")
        for row in rows:
            lines.append(
                "  " + "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip()
            )

    solver_text = params.get("solver")
    if solver_text:
        lines.append("")
        lines.append("  solver")
        solver = _json_or_none(solver_text)
        if isinstance(solver, dict):
            width = max((len(str(k)) for k in solver), default=0)
            lines += [f"    {str(k).ljust(width)}  {v}" for k, v in solver.items()]
        else:
            lines += [f"    {line}" for line in solver_text.splitlines()]
    return "\n".join(lines)
