"""Trajectory files: the HDF5 (H5MD 1.1) writer and reader.

Layout (docs/format.md, "Trajectories")::

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

In 3D the box has dimension 3; position and velocity are
(T,N,3), orientation (T,N,4) (w, x, y, z), angular_velocity (T,N,3) world frame, and
angular_momentum (T,N,3) world frame about each centre of mass; there is no `angle`.
moment_of_inertia is (N,3,3) (body frame, about the COM), center_of_mass (N,3), the shape
vertices (V,3); the shapes add face_start, face_count (S,) int32 and faces (F,3) int32
(triangles, counter-clockwise seen from outside, indices local to the shape's vertex
rows) and normal (S,3) (a plane's outward normal, zeros otherwise). The observables
linear_momentum and angular_momentum (about the world origin) are (T,3).

Contact points (output.contacts: points; rbsim's engine) are rows of their own, C in all,
frame after frame::

    /contacts/start, /contacts/count    step, time (links), value (T,) int64: each frame's
                                        first row and number of points
    /contacts/body                      (C,2) int32: the two bodies, rows of
                                        /particles/bodies then /particles/static; -1 not stored
    /contacts/position                  (C,D) m, world frame, where the bodies meet
    /contacts/normal                    (C,D) unit, from the first body towards the second
    /contacts/force                     (C,) N, the mean normal force over the step (the
                                        point's normal impulse in the step / dt)

A quaternion and its negative are one rotation: the writer makes the stored sign
continuous from frame to frame (a frame's q is negated when its dot product with the
previous written frame's is negative), whatever sign the engine holds.

`step` and `time` are created once, under `position`, and hard-linked into every other
time series group (H5MD allows shared step and time datasets).

Durability: the HDF5 library never holds the file open for writing while frames are
written. The writer lays the whole file out at once (under a temporary name, renamed
over the path): static data, parameters, and each time series as a contiguous dataset
with room for the frames the run will write (at most ROOM_FRAMES and ROOM_BYTES of them
at first; laid out anew with twice the room as it fills). Frames are then written in
place with os.pwrite, `step` last, so that at every moment the file is a valid HDF5 file (plain
h5py, h5dump) whose frames are those with step >= 0. A closed file holds exactly its
frames, but for a stopped run's with more than STOP_COPY_BYTES of them, closed in place
with its room (the checkpoint beside it). `OUT.h5.resume` beside a running file is the
engine checkpoint of the last flush (docs/design.md, "Output").
"""

from __future__ import annotations

import contextlib
import difflib
import getpass
import json
import math
import os
import re
import struct
import time as _time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from types import TracebackType

import h5py
import numpy as np

from ..scene.schema import counted
from ..scene.types import BODY_TYPES, SHAPE_KINDS, SHAPE_KINDS_3D

__all__ = [
    "BodyTable",
    "ContactPoints",
    "Trajectory",
    "TrajectoryWriter",
    "load_trajectory",
    "summarize",
]

H5MD_VERSION = (1, 1)
# H5MD's units module (h5md/modules/units): its version, and the unit system every unit
# string is of
UNITS_MODULE_VERSION = (1, 0)
UNIT_SYSTEM = "SI"
STATUS_RUNNING = "running"
STATUS_INTERRUPTED = "interrupted"

# Per-body time series: name -> (components per body, unit). 0 components = (T,N).
BODY_SERIES: dict[str, tuple[int, str | None]] = {
    "position": (2, "m"),
    "orientation": (2, None),
    "angle": (0, "rad"),
    "velocity": (2, "m s-1"),
    "angular_velocity": (0, "rad s-1"),
}
# The same in 3D: orientation (w, x, y, z); no angle; the angular momentum per body.
BODY_SERIES_3D: dict[str, tuple[int, str | None]] = {
    "position": (3, "m"),
    "orientation": (4, None),
    "velocity": (3, "m s-1"),
    "angular_velocity": (3, "rad s-1"),
    "angular_momentum": (3, "kg m2 s-1"),
}
# Every per-body series name of either dimension.
ALL_BODY_SERIES = tuple(dict.fromkeys([*BODY_SERIES, *BODY_SERIES_3D]))


def body_series(dimension: int) -> dict[str, tuple[int, str | None]]:
    """The per-body time series of a trajectory of `dimension` (2 or 3)."""
    return BODY_SERIES_3D if dimension == 3 else BODY_SERIES


def block_key(name: str) -> str:
    """The key of the per-body series `name` in a writer's block: its name, except the
    per-body angular momentum (3D), "body_angular_momentum", which would clash with the
    observable of the same name."""
    return "body_angular_momentum" if name == "angular_momentum" else name


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
    """Static per-body data of N bodies made of S shapes with V vertices in all, in a
    world of `dimension` D (2 or 3).

    name: (N,) unique body names. type: (N,) "dynamic" | "static" | "kinematic".
    mass: (N,) kg, inf for static and kinematic bodies.
    moment_of_inertia: (N,) kg m² in 2D, (N,3,3) the full tensor in body axes in 3D,
        about the centre of mass; inf (diag(inf, inf, inf) in 3D) likewise.
    center_of_mass: (N,D) m, in the body frame (offset from the body origin).
    shape_body: (S,) int32, index of the body each shape belongs to.
    shape_kind: (S,) "circle" | "box" | "polygon" | "segment" (2D); "sphere" | "box" |
        "capsule" | "convex" | "plane" (3D).
    shape_radius: (S,) m; circle, sphere or capsule radius, segment radius, 0 otherwise.
    shape_vertex_start, shape_vertex_count: (S,) int32, each shape's rows of
        shape_vertices (circle, sphere: its centre; segment, capsule: a, b; box/polygon:
        CCW corners; 3D box: its 8 corners; convex: its hull's vertices; plane: one point).
    shape_vertices: (V,D) m, body frame (from the body origin).
    shape_face_start, shape_face_count: (S,) int32, each shape's rows of shape_faces
        (3D box and convex; 0 faces otherwise, and in 2D).
    shape_faces: (F,3) int32, triangles as indices into the shape's own vertex rows,
        counter-clockwise seen from outside.
    shape_normal: (S,3) a plane's unit outward normal, body frame; zeros otherwise.

    Array fields are converted to numpy arrays of the stated dtypes on construction.
    The face and normal fields default to none (2D, or shapes without faces).
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
    shape_face_start: np.ndarray | None = None
    shape_face_count: np.ndarray | None = None
    shape_faces: np.ndarray | None = None
    shape_normal: np.ndarray | None = None
    dimension: int = 2

    def __post_init__(self) -> None:
        d = int(self.dimension)
        if d not in (2, 3):
            raise ValueError(f"BodyTable.dimension must be 2 or 3, got {self.dimension!r}")
        self.dimension = d
        self.name = [str(s) for s in self.name]
        self.type = [str(s) for s in self.type]
        self.shape_kind = [str(s) for s in self.shape_kind]
        s = len(self.shape_kind)
        inertia = (-1, 3, 3) if d == 3 else (-1,)
        self.mass = np.asarray(self.mass, dtype=np.float64).reshape(-1)
        self.moment_of_inertia = np.asarray(self.moment_of_inertia, np.float64).reshape(inertia)
        self.center_of_mass = np.asarray(self.center_of_mass, dtype=np.float64).reshape(-1, d)
        self.shape_body = np.asarray(self.shape_body, dtype=np.int32).reshape(-1)
        self.shape_radius = np.asarray(self.shape_radius, dtype=np.float64).reshape(-1)
        self.shape_vertex_start = np.asarray(self.shape_vertex_start, dtype=np.int32).reshape(-1)
        self.shape_vertex_count = np.asarray(self.shape_vertex_count, dtype=np.int32).reshape(-1)
        self.shape_vertices = np.asarray(self.shape_vertices, dtype=np.float64).reshape(-1, d)

        def rows(value: np.ndarray | None, shape: tuple[int, ...], dtype: type) -> np.ndarray:
            if value is None:
                return np.zeros(tuple(s if k == -1 else k for k in shape), dtype)
            return np.asarray(value, dtype=dtype).reshape(shape)

        self.shape_face_start = rows(self.shape_face_start, (-1,), np.int32)
        self.shape_face_count = rows(self.shape_face_count, (-1,), np.int32)
        faces = self.shape_faces
        self.shape_faces = (
            np.zeros((0, 3), np.int32) if faces is None else rows(faces, (-1, 3), np.int32)
        )
        self.shape_normal = rows(self.shape_normal, (-1, 3), np.float64)
        self._check()

    def __len__(self) -> int:
        return len(self.name)

    def joined(self, other: BodyTable) -> BodyTable:
        """This table's bodies followed by `other`'s, with their shapes."""
        if other.dimension != self.dimension:
            raise ValueError("BodyTable.joined: tables of different dimensions")
        n, v, f = len(self), len(self.shape_vertices), len(self.shape_faces)
        return BodyTable(
            name=self.name + other.name,
            type=self.type + other.type,
            mass=np.concatenate([self.mass, other.mass]),
            moment_of_inertia=np.concatenate([self.moment_of_inertia, other.moment_of_inertia]),
            center_of_mass=np.concatenate([self.center_of_mass, other.center_of_mass]),
            shape_body=np.concatenate([self.shape_body, other.shape_body + n]),
            shape_kind=self.shape_kind + other.shape_kind,
            shape_radius=np.concatenate([self.shape_radius, other.shape_radius]),
            shape_vertex_start=np.concatenate(
                [self.shape_vertex_start, other.shape_vertex_start + v]
            ),
            shape_vertex_count=np.concatenate([self.shape_vertex_count, other.shape_vertex_count]),
            shape_vertices=np.concatenate([self.shape_vertices, other.shape_vertices]),
            shape_face_start=np.concatenate([self.shape_face_start, other.shape_face_start + f]),
            shape_face_count=np.concatenate([self.shape_face_count, other.shape_face_count]),
            shape_faces=np.concatenate([self.shape_faces, other.shape_faces]),
            shape_normal=np.concatenate([self.shape_normal, other.shape_normal]),
            dimension=self.dimension,
        )

    def subset(self, rows: list[int] | np.ndarray) -> BodyTable:
        """The table of the bodies `rows` (in that order), with their shapes."""
        rows = [int(r) for r in rows]
        shape_rows: list[int] = []
        for r in rows:
            shape_rows += [int(k) for k in np.flatnonzero(self.shape_body == r)]
        new_index = {r: i for i, r in enumerate(rows)}
        starts, verts, face_starts, faces = [], [], [], []
        for k in shape_rows:
            a, n = int(self.shape_vertex_start[k]), int(self.shape_vertex_count[k])
            starts.append(sum(len(v) for v in verts))
            verts.append(self.shape_vertices[a : a + n])
            a, n = int(self.shape_face_start[k]), int(self.shape_face_count[k])
            face_starts.append(sum(len(f) for f in faces))
            faces.append(self.shape_faces[a : a + n])
        d = self.dimension
        return BodyTable(
            name=[self.name[r] for r in rows],
            type=[self.type[r] for r in rows],
            mass=self.mass[rows],
            moment_of_inertia=self.moment_of_inertia[rows],
            center_of_mass=self.center_of_mass[rows],
            shape_body=[new_index[int(self.shape_body[k])] for k in shape_rows],
            shape_kind=[self.shape_kind[k] for k in shape_rows],
            shape_radius=self.shape_radius[shape_rows],
            shape_vertex_start=starts,
            shape_vertex_count=self.shape_vertex_count[shape_rows],
            shape_vertices=np.concatenate(verts) if verts else np.zeros((0, d)),
            shape_face_start=face_starts,
            shape_face_count=self.shape_face_count[shape_rows],
            shape_faces=np.concatenate(faces) if faces else np.zeros((0, 3), np.int32),
            shape_normal=self.shape_normal[shape_rows],
            dimension=d,
        )

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
            ("shape_face_start", len(self.shape_face_start), s),
            ("shape_face_count", len(self.shape_face_count), s),
            ("shape_normal", len(self.shape_normal), s),
        ):
            if length != expected:
                raise ValueError(f"BodyTable.{field_name} has {length} rows, expected {expected}")
        bad_types = sorted(set(self.type) - set(BODY_TYPES))
        if bad_types:
            raise ValueError(f"BodyTable.type: unknown {bad_types}, expected one of {BODY_TYPES}")
        kinds = SHAPE_KINDS_3D if self.dimension == 3 else SHAPE_KINDS
        bad_kinds = sorted(set(self.shape_kind) - set(kinds))
        if bad_kinds:
            raise ValueError(f"BodyTable.shape_kind: unknown {bad_kinds}, expected one of {kinds}")
        if s and (self.shape_body.min() < 0 or self.shape_body.max() >= n):
            raise ValueError(f"BodyTable.shape_body: indices must lie in [0, {n})")
        end = self.shape_vertex_start.astype(np.int64) + self.shape_vertex_count
        if s and (self.shape_vertex_start.min() < 0 or end.max() > v):
            raise ValueError(f"BodyTable.shape_vertex_start/count: rows must lie in [0, {v})")
        nf = len(self.shape_faces)
        end = self.shape_face_start.astype(np.int64) + self.shape_face_count
        if s and (
            self.shape_face_start.min() < 0 or self.shape_face_count.min() < 0 or end.max() > nf
        ):
            raise ValueError(f"BodyTable.shape_face_start/count: rows must lie in [0, {nf})")
        for field_name in ("center_of_mass", "shape_radius", "shape_vertices", "shape_normal"):
            if not np.isfinite(np.asarray(getattr(self, field_name), dtype=float)).all():
                raise ValueError(f"BodyTable.{field_name}: values must be finite")
        for field_name in ("mass", "moment_of_inertia"):  # inf for a static body
            if np.isnan(np.asarray(getattr(self, field_name), dtype=float)).any():
                raise ValueError(f"BodyTable.{field_name}: values must not be NaN")
        for k in np.flatnonzero(self.shape_face_count):
            a, n = int(self.shape_face_start[k]), int(self.shape_face_count[k])
            tri = self.shape_faces[a : a + n]
            if tri.min() < 0 or tri.max() >= self.shape_vertex_count[k]:
                raise ValueError(
                    f"BodyTable.shape_faces: shape {k}'s faces must index its "
                    f"{int(self.shape_vertex_count[k])} vertices"
                )


def ascii_attr(text: str) -> np.bytes_:
    """An attribute value that h5py writes as a fixed-length ASCII string (as H5MD's units
    module has a `unit` and its `system`; a str is written variable-length UTF-8)."""
    return np.bytes_(text.encode("ascii"))


def set_unit(ds: h5py.Dataset, unit: str) -> None:
    """Give dataset `ds` its H5MD `unit` attribute (a unit string of the SI system, as
    "kg m2 s-1")."""
    ds.attrs["unit"] = ascii_attr(unit)


def attr_text(value: object) -> str:
    """An attribute's text, whether written fixed-length (bytes) or variable-length
    (str, as files of rbsim before 2026-12-06 have their units)."""
    return value.decode("ascii") if isinstance(value, bytes) else str(value)


def _write_body_table(group: h5py.Group, bodies: BodyTable) -> None:
    group.create_dataset("name", data=np.array(bodies.name, dtype=object), dtype=_STR)
    group.create_dataset("type", data=np.array(bodies.type, dtype=object), dtype=_STR)
    set_unit(group.create_dataset("mass", data=bodies.mass), "kg")
    set_unit(group.create_dataset("moment_of_inertia", data=bodies.moment_of_inertia), "kg m2")
    set_unit(group.create_dataset("center_of_mass", data=bodies.center_of_mass), "m")
    shapes = group.create_group("shapes")
    shapes.create_dataset("body", data=bodies.shape_body)
    shapes.create_dataset("kind", data=np.array(bodies.shape_kind, dtype=object), dtype=_STR)
    set_unit(shapes.create_dataset("radius", data=bodies.shape_radius), "m")
    shapes.create_dataset("vertex_start", data=bodies.shape_vertex_start)
    shapes.create_dataset("vertex_count", data=bodies.shape_vertex_count)
    set_unit(shapes.create_dataset("vertices", data=bodies.shape_vertices), "m")
    if bodies.dimension == 3:
        shapes.create_dataset("face_start", data=bodies.shape_face_start)
        shapes.create_dataset("face_count", data=bodies.shape_face_count)
        shapes.create_dataset("faces", data=bodies.shape_faces)
        shapes.create_dataset("normal", data=bodies.shape_normal)


def _write_box(group: h5py.Group, dimension: int) -> None:
    box = group.create_group("box")
    box.attrs["dimension"] = np.int32(dimension)
    box.attrs["boundary"] = np.array(["none"] * dimension, dtype=_STR)


def _read_dimension(group: h5py.Group) -> int:
    """The box's dimension of a particles group (2 when not recorded)."""
    box = group.get("box")
    return int(box.attrs.get("dimension", 2)) if box is not None else 2


def _read_strings(dataset: h5py.Dataset) -> list[str]:
    return [str(s) for s in dataset.asstr()[()]]


def read_body_table(group: h5py.Group) -> BodyTable:
    """The per-body table of an open file's /particles/bodies group."""
    shapes = group["shapes"]
    faces = {}
    if _read_dimension(group) == 3:
        faces = {
            "shape_face_start": shapes["face_start"][()],
            "shape_face_count": shapes["face_count"][()],
            "shape_faces": shapes["faces"][()],
            "shape_normal": shapes["normal"][()],
            "dimension": 3,
        }
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
        **faces,
    )


# ---------------------------------------------------------------------------------------
# Writer
# ---------------------------------------------------------------------------------------

# The standard observables: name -> (shape per frame, dtype).
OBSERVABLES: dict[str, tuple[tuple[int, ...], str]] = {
    "kinetic_energy": ((), "f8"),
    "potential_energy": ((), "f8"),
    "linear_momentum": ((2,), "f8"),
    "angular_momentum": ((), "f8"),
    "contact_count": ((), "i8"),
}
# The same in 3D: the momenta are vectors (angular momentum about the world origin).
OBSERVABLES_3D: dict[str, tuple[tuple[int, ...], str]] = {
    "kinetic_energy": ((), "f8"),
    "potential_energy": ((), "f8"),
    "linear_momentum": ((3,), "f8"),
    "angular_momentum": ((3,), "f8"),
    "contact_count": ((), "i8"),
}


def observables_spec(dimension: int) -> dict[str, tuple[tuple[int, ...], str]]:
    """The standard observables of a trajectory of `dimension` (2 or 3)."""
    return OBSERVABLES_3D if dimension == 3 else OBSERVABLES


PRECISIONS = ("float64", "float32")
COMPRESSIONS = ("none", "lzf", "gzip")
# Frames the writer gathers before it writes them out: as many as fill BLOCK_BYTES of
# per-frame data, within [1, BLOCK_MAX_FRAMES]. This bounds its memory: a block holds at
# most max(one frame, BLOCK_BYTES) (plus the same again while a float32 copy is made).
BLOCK_BYTES = 8 << 20
BLOCK_MAX_FRAMES = 256
# Contact point rows: per row the two bodies, position, normal and force (the block's
# keys contact_body, ...; the file's /contacts/body, ...). CONTACT_BLOCK_ROWS rows per
# frame of the block to start with (grow_contact_rows adds room when a frame needs it);
# the file makes room for CONTACT_FILE_ROWS rows per frame at first and grows as needed.
CONTACT_ROW_SERIES = ("body", "position", "normal", "force")
CONTACT_BLOCK_ROWS = 16
CONTACT_FILE_ROWS = 8
# Frames a writer that was not told how many to expect makes room for at first; the
# room doubles (the file is laid out anew) when it runs out.
INITIAL_FRAMES = 64
# The most room a writer makes at first, however many frames it was told to expect:
# ROOM_FRAMES frames (their step and time are written when the room is made, -1 and NaN:
# 16 bytes a frame, 4 MiB here) and ROOM_BYTES bytes of frames in all (the rest is left
# unwritten, sparse on disk). Room for a run's every frame at once made a scene of one
# ball with 1e9 steps write 16 GB of step and time before its first step (450 MB/s, and
# a Ctrl-C waited for it); a longer run's room doubles as it fills (`make_room`).
ROOM_FRAMES = 1 << 18
ROOM_BYTES = 8 << 30
# The most bytes of frames that closing a stopped run copies into a file of exactly its
# frames (its checkpoint inside); a larger one keeps its room and the checkpoint beside
# it, closed in place: the copy of 1 GB of frames made Ctrl-C on a pile of 20,000 boxes
# wait 3 s (about 0.35 GB/s on a shared disk; 64 MB: a fifth of a second).
STOP_COPY_BYTES = 64 << 20
# Chunks of a compressed file: whole frames, about this many bytes.
CHUNK_TARGET_BYTES = 1 << 20
CHUNK_MAX_FRAMES = 64
# Chunks copied at a time into the closed file's layout, a stop() asked between them:
# about 8 MB, a tenth of a second or two of gzip
COPY_CHUNKS = 8
# Fixed byte lengths of the status and wall-time strings, rewritten in place at close.
STATUS_BYTES = 256
WALL_TIME_BYTES = 32
# The engine checkpoint written beside a running trajectory (OUT.h5 + this suffix).
CHECKPOINT_SUFFIX = ".resume"
# A checkpoint file: magic, frames and step (two little-endian int64), the identifier of
# the trajectory that wrote it (TRAJECTORY_ID_BYTES of ASCII hex), then the engine's bytes.
# Format 1 (no identifier) is still read, with the identifier "".
_CHECKPOINT_MAGIC = b"RBSIMRS2"
_CHECKPOINT_MAGIC_1 = b"RBSIMRS1"
# /parameters/rbsim/trajectory_id: a digest of a new run's parameters, kept when it is
# resumed; its checkpoints record it, and resume uses only a checkpoint that matches.
TRAJECTORY_ID = "trajectory_id"
TRAJECTORY_ID_BYTES = 32

_STR = h5py.string_dtype("utf-8")


def _fixed(nbytes: int) -> np.dtype:
    return h5py.string_dtype("utf-8", nbytes)


def _dcpl(fill: float | int | None = None, dtype: str = "f8") -> h5py.h5p.PropDCID:
    """Contiguous, allocated when created; written with `fill` then, or left unwritten."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_layout(h5py.h5d.CONTIGUOUS)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    if fill is None:
        dcpl.set_fill_time(h5py.h5d.FILL_TIME_NEVER)
    else:
        dcpl.set_fill_time(h5py.h5d.FILL_TIME_ALLOC)
        dcpl.set_fill_value(np.array(fill, dtype=dtype))
    return dcpl


@dataclass
class FixedBodies:
    """Bodies stored once rather than in every frame (static bodies that `output.bodies`
    leaves out): their table, and their pose: position (K,D) m, orientation (K,2) (cos θ,
    sin θ) / (K,4) (w, x, y, z), angle (K,) rad (None in 3D). Stored under
    /particles/static, as time-independent H5MD elements."""

    bodies: BodyTable
    position: np.ndarray
    orientation: np.ndarray
    angle: np.ndarray | None


@dataclass
class _Series:
    """One time-dependent dataset: its path, per-frame shape, dtype on file, the block
    key it is filled from, and its byte offset in the file (contiguous layout)."""

    path: str
    frame: tuple[int, ...]
    dtype: np.dtype
    key: str
    offset: int = -1
    rows: bool = False  # a contact row series: (C, *frame), not one row per frame

    @property
    def frame_bytes(self) -> int:
        return math.prod(self.frame) * self.dtype.itemsize


def grow_contact_rows(block: dict[str, np.ndarray], extra: int) -> None:
    """Make room for at least `extra` more contact rows in a writer's `block` (its
    contact_body, contact_position, contact_normal and contact_force arrays are replaced
    by larger ones holding the same first rows)."""
    old = len(block["contact_force"])
    rows = max(2 * old, old + int(extra))
    for name in CONTACT_ROW_SERIES:
        a = block[f"contact_{name}"]
        grown = np.zeros((rows, *a.shape[1:]), a.dtype)
        grown[:old] = a
        block[f"contact_{name}"] = grown


# bytes of a checkpoint written between two asks of write_checkpoint's `stop`
CHECKPOINT_CHUNK = 1 << 26


def trajectory_id(parameters: dict[str, str]) -> str:
    """The identifier of a new trajectory with these /parameters/rbsim entries: the
    first TRAJECTORY_ID_BYTES hex digits of the SHA-256 of their sorted JSON (a digest,
    so that a run's file stays deterministic; two runs with the same parameters make the
    same frames, and may share a checkpoint)."""
    import hashlib

    text = json.dumps(parameters, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:TRAJECTORY_ID_BYTES]


def write_checkpoint(
    path: str,
    frames: int,
    step: int,
    data: bytes,
    stop: Callable[[], bool] | None = None,
    owner: str = "",
) -> bool:
    """Write the engine checkpoint of a running trajectory at `path` atomically (a
    temporary file renamed over it): `frames` frames are on file, the last at `step`;
    `owner` is the trajectory's identifier (TRAJECTORY_ID), which resume checks.
    stop() is asked between chunks of CHECKPOINT_CHUNK bytes (a large world's checkpoint
    is hundreds of MB); when true the write is dropped, the file at `path` left as it
    was, and False returned."""
    tmp = f"{path}.tmp"
    view = memoryview(data)
    dropped = False
    try:
        with open(tmp, "wb") as f:
            tag = owner.encode("ascii").ljust(TRAJECTORY_ID_BYTES, b"\0")[:TRAJECTORY_ID_BYTES]
            f.write(_CHECKPOINT_MAGIC + struct.pack("<qq", frames, step) + tag)
            for start in range(0, len(view), CHECKPOINT_CHUNK):
                dropped = stop is not None and stop()
                if dropped:
                    break
                f.write(view[start : start + CHECKPOINT_CHUNK])
        if not dropped:
            os.replace(tmp, path)
            return True
    except BaseException:
        # a full disk (or a signal) midway: the half-written file is no checkpoint, and
        # would hold the disk's last room (the last whole one at `path` stays)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    os.unlink(tmp)
    return False


def read_checkpoint(path: str) -> tuple[int, int, bytes, str] | None:
    """(frames, step, engine bytes, owner) of a checkpoint file, or None if it is not
    one; owner: the identifier of the trajectory that wrote it ("" in format 1)."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError:
        return None
    if len(raw) >= 24 and raw.startswith(_CHECKPOINT_MAGIC_1):
        frames, step = struct.unpack("<qq", raw[8:24])
        return frames, step, raw[24:], ""
    end = 24 + TRAJECTORY_ID_BYTES
    if len(raw) < end or not raw.startswith(_CHECKPOINT_MAGIC):
        return None
    frames, step = struct.unpack("<qq", raw[8:24])
    owner = raw[24:end].rstrip(b"\0").decode("ascii", "replace")
    return frames, step, raw[end:], owner


def remove_dead_layouts(path: str) -> None:
    """Remove the files a writer of `path` was laying out (PATH.tmp-<pid>, its whole file
    written anew) when its process died (kill -9 during a large file's compression left
    tens of MB that no later run at that path would find). A live process's is kept."""
    folder, name = os.path.split(os.path.abspath(path))
    prefix = name + ".tmp-"
    with contextlib.suppress(OSError):
        for entry in os.listdir(folder):
            pid = entry[len(prefix) :]
            if not entry.startswith(prefix) or not pid.isdigit() or int(pid) == os.getpid():
                continue
            if _process_lives(int(pid)):
                continue  # (or another user's: not ours to remove)
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(folder, entry))


def _process_lives(pid: int) -> bool:
    """Whether process `pid` runs (a zombie, killed and not yet reaped, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # another user's
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
            return f.read().rpartition(")")[2].split()[:1] != ["Z"]
    except OSError:
        return True


class LayoutStopped(KeyboardInterrupt):
    """A writer's final layout (the compression at close) stopped by a signal: the file
    keeps every frame, uncompressed, with status "interrupted" (TrajectoryWriter.close)."""


class TrajectoryWriter:
    """Writes an rbsim trajectory (H5MD 1.1), gathering frames in blocks.

    path: the .h5 file to create (replaced if it exists).
    bodies: static data of the bodies written in every frame.
    parameters: strings stored under /parameters/rbsim ("scene" YAML text, "resolved_scene"
        and "solver" JSON, ...). "engine" is added from `engine`; "status" and
        "wall_time" are the writer's.
    engine: "rbsim" or "pymunk", the engine that computed the frames.
    flush_seconds: the longest wall time, s, between writes to disk (`flush_due`); a
        killed writer loses at most the frames of the last `flush_seconds`.
    frames: how many frames the run will write (room is made for them, at most
        ROOM_FRAMES and ROOM_BYTES at first, doubled by `make_room` or a block's write as
        it fills; without it the room starts at INITIAL_FRAMES and doubles alike).
    precision: "float64" or "float32" for the per-body series (step, time and the
        observables stay as they are).
    compression: "none", "lzf" or "gzip"; applied when the file is closed (until then
        the file is uncompressed, so that a killed run leaves a readable file).
    select: indices of the `bodies` rows among the rows of what is appended (the
        engine's bodies), or None when they are the same.
    block_bodies: rows per frame of what is appended (default len(bodies)).
    fixed: bodies stored once (FixedBodies), or None.
    observables: name -> (shape, dtype) of each observable (default OBSERVABLES); when
        None and frames are appended with `append`, the first frame's decide.
    keep: resume: keep the first `keep` frames of the trajectory already at `path`.
    started: time.perf_counter() when this run (segment) started (default: now).
    wall_before: s of wall time of the run's earlier segments (resume: what the file
        records); the wall time recorded is their sum with this one's, rewritten at
        every flush (a killed run keeps it to its last flush) and at close.
    contacts: record each frame's contact points (/contacts; the block's contact_* keys,
        which the engine fills, see `block`).
    contact_bodies: (rows of what is appended,) the index of each appended body in the
        file's contact records (its row of `bodies`, then len(bodies) + its row of
        `fixed`, or -1), or None when the rows are the same.

    Durability: the file is only ever replaced whole (written under a temporary name and
    renamed) or written in place inside datasets whose room was made when it was laid
    out, with the frames' `step` last. So a kill at any moment leaves a file that any
    HDF5 reader opens, holding every frame flushed so far: the frames whose step is >= 0
    (the unwritten rows read as step -1).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        bodies: BodyTable,
        parameters: dict[str, str],
        engine: str = "rbsim",
        flush_seconds: float = 1.0,
        frames: int | None = None,
        precision: str = "float64",
        compression: str = "none",
        select: np.ndarray | None = None,
        block_bodies: int | None = None,
        fixed: FixedBodies | None = None,
        observables: dict[str, tuple[tuple[int, ...], str]] | None = None,
        keep: int = 0,
        contacts: bool = False,
        contact_bodies: np.ndarray | None = None,
        started: float | None = None,
        wall_before: float = 0.0,
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
        if not keep:  # a new trajectory; a resumed one keeps the identifier it has
            params.setdefault(TRAJECTORY_ID, trajectory_id(params))
        if flush_seconds < 0:
            raise ValueError(f"flush_seconds must be >= 0, got {flush_seconds}")
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}, got {precision!r}")
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {COMPRESSIONS}, got {compression!r}")

        self.path = os.fspath(path)
        self.checkpoint_path = self.path + CHECKPOINT_SUFFIX
        if not keep:
            # a checkpoint left at this path by an earlier run (killed) is not this run's:
            # removed before this run writes anything, so that it never resumes this one
            for stale in (self.checkpoint_path, f"{self.checkpoint_path}.tmp"):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(stale)
        remove_dead_layouts(self.path)
        self.bodies = bodies
        self.engine = engine
        self.parameters = params
        self.flush_seconds = float(flush_seconds)
        self.precision = precision
        self.compression = compression
        self.fixed = fixed
        self.dimension = bodies.dimension
        self._body_series = body_series(self.dimension)
        self._body_keys = {block_key(name) for name in self._body_series}
        # the last orientation written per body (3D): the next frame's sign follows it
        self._last_q: np.ndarray | None = None
        self._n = len(bodies)
        self._block_n = self._n if block_bodies is None else int(block_bodies)
        self._select = None if select is None else np.asarray(select, np.intp)
        if self._select is None and self._block_n != self._n:
            raise ValueError("block_bodies differs from len(bodies) but no select is given")
        # the frames the run will write (None: not told), and the room made for them so
        # far: all of them, up to ROOM_FRAMES and ROOM_BYTES at first (see make_room)
        self._frames_total = max(1, int(frames)) if frames is not None else None
        self._spec = dict(observables) if observables is not None else None
        self._capacity = self._first_room(int(keep))
        self.frames_written = 0  # frames appended (on file or in the block)
        self.frames_flushed = 0  # frames on file
        self._rows = 0  # frames in the block
        self._closed = False
        # the wall time recorded: wall_before + the time since `started` (this segment)
        self._started = _time.perf_counter() if started is None else float(started)
        self.wall_before = float(wall_before)
        self.wall_time = math.nan  # s recorded at close: every segment of the run
        self._last_flush = _time.monotonic()
        self._fd: int | None = None
        self._series: list[_Series] = []
        self._block: dict[str, np.ndarray] | None = None
        self._status_offset = self._wall_offset = -1
        self._last_step = -1
        self.contacts = bool(contacts)
        self._contact_map = None if contact_bodies is None else np.asarray(contact_bodies, np.int64)
        self.contact_rows_flushed = 0  # contact rows on file
        self._contact_capacity = CONTACT_FILE_ROWS * self._capacity if contacts else 0
        if keep:
            self.frames_written = self.frames_flushed = int(keep)
            if self.contacts:
                with open_for_reading(self.path) as f:
                    last = keep - 1
                    self.contact_rows_flushed = int(
                        f["contacts/start/value"][last] + f["contacts/count/value"][last]
                    )
                self._contact_capacity = max(self._contact_capacity, self.contact_rows_flushed)
        if self._spec is None:
            self._layout(self._capacity, keep_from=None, series=False)
        else:
            self._layout(self._capacity, keep_from=self.path if keep else None, series=True)
        if keep and self.dimension == 3:
            with open_for_reading(self.path) as f:
                q = f["particles/bodies/orientation/value"][self.frames_flushed - 1]
            self._last_q = np.asarray(q, np.float64)

    # -- layout ---------------------------------------------------------------------------

    def _frame_bytes(self) -> int:
        """Bytes a frame takes on file (before compression): its per-body series, step,
        time, and the observables (16 values when they are not known yet)."""
        width = 4 if self.precision == "float32" else 8
        per_body = sum(max(1, c) for c, _unit in self._body_series.values())
        spec = self._spec if self._spec is not None else {"?": ((16,), "f8")}
        observed = sum(8 * math.prod(shape) for shape, _dtype in spec.values())
        return width * self._n * per_body + 16 + observed

    def _first_room(self, keep: int) -> int:
        """Frames of room to make at first, the first `keep` (resume) included: every
        frame the run will write, but at most ROOM_FRAMES and ROOM_BYTES more than `keep`
        (at least INITIAL_FRAMES); INITIAL_FRAMES more when the writer was not told."""
        if self._frames_total is None:
            return keep + INITIAL_FRAMES
        room = min(ROOM_FRAMES, ROOM_BYTES // max(1, self._frame_bytes()))
        return max(keep, min(self._frames_total, keep + max(INITIAL_FRAMES, room)))

    @property
    def room(self) -> int:
        """Frames the file has room for beyond those on it and in the block; when 0,
        `make_room` makes more."""
        return self._capacity - self.frames_flushed - self._rows

    def make_room(self, stop: Callable[[], bool] | None = None) -> None:
        """Write the block's frames, and lay the file out anew with twice the room (up
        to the frames the run will write), when the block's frames fill it. stop() is
        asked while the frames on file are copied (1 GB: seconds); true, it raises
        LayoutStopped with the file at `path` as it was, holding every frame."""
        if self._closed or self.room > 0:
            return
        self._write_block()
        self._grow(self.frames_flushed, stop)

    def _grow(self, frames: int, stop: Callable[[], bool] | None = None) -> None:
        """Lay the file out anew with room for at least `frames` frames: twice the room
        it has, capped at the frames the run will write (a writer told how many)."""
        capacity = max(2 * self._capacity, frames)
        if self._frames_total is not None:
            if frames > self._frames_total:
                raise ValueError(
                    f"{self.path}: more frames than the {self._frames_total} the writer was told"
                )
            capacity = min(capacity, self._frames_total)
        if capacity > self._capacity:
            self._layout(capacity, keep_from=self.path, series=True, stop=stop)

    def _plan(self) -> list[_Series]:
        """Every time-dependent dataset, in write order (`step` last)."""
        assert self._spec is not None
        body_dtype = np.dtype("<f4" if self.precision == "float32" else "<f8")
        plan = [_Series("particles/bodies/position/time", (), np.dtype("<f8"), "time")]
        for name, (components, _unit) in self._body_series.items():
            frame = (self._n, components) if components else (self._n,)
            plan.append(
                _Series(f"particles/bodies/{name}/value", frame, body_dtype, block_key(name))
            )
        for name, (shape, dtype) in self._spec.items():
            dt = np.dtype("<i8") if np.dtype(dtype).kind in "iub" else np.dtype("<f8")
            plan.append(_Series(f"observables/{name}/value", tuple(shape), dt, name))
        if self.contacts:
            d = self.dimension
            rows = {"body": ((2,), np.dtype("<i4")), "position": ((d,), body_dtype)}
            rows |= {"normal": ((d,), body_dtype), "force": ((), body_dtype)}
            for name in CONTACT_ROW_SERIES:
                frame, dt = rows[name]
                plan.append(_Series(f"contacts/{name}", frame, dt, f"contact_{name}", rows=True))
            i8 = np.dtype("<i8")
            plan.append(_Series("contacts/start/value", (), i8, "contact_start"))
            plan.append(_Series("contacts/count/value", (), i8, "contact_points"))
        plan.append(_Series("particles/bodies/position/step", (), np.dtype("<i8"), "step"))
        return plan

    def _layout(
        self,
        capacity: int,
        keep_from: str | None,
        series: bool,
        final: bool = False,
        status: str = STATUS_RUNNING,
        wall_time: str = "",
        checkpoint: bytes | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> None:
        """Write the whole file anew under a temporary name and rename it over `path`:
        static data, parameters, and (with `series`) room for `capacity` frames, with the
        first frames_flushed frames copied from the file `keep_from`. `final`: the closed
        file: exactly frames_flushed frames, chunked and compressed as asked (no room).
        A true stop(), asked while the frames are copied, raises LayoutStopped with the
        file at `path` as it was."""
        reopen = self._fd is not None  # (stopped or failed, the file at `path` is written on)
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        tmp = f"{self.path}.tmp-{os.getpid()}"
        keep = self.frames_flushed
        if final:
            self._contact_capacity = self.contact_rows_flushed
        old = open_for_reading(keep_from) if keep_from is not None and keep else None
        # the file at `path`'s, until replaced
        offsets = self._status_offset, self._wall_offset
        series_before, contact_before = self._series, self._contact_capacity
        try:
            with h5py.File(tmp, "w", libver="earliest") as f:
                self._write_static(f, status, wall_time, checkpoint)
                if series:
                    self._series = self._plan()
                    self._write_series(f, capacity, old, keep, final, stop)
        except BaseException:
            self._status_offset, self._wall_offset = offsets
            self._series, self._contact_capacity = series_before, contact_before
            if old is not None:
                old.close()
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            if reopen:
                with contextlib.suppress(OSError):
                    self._fd = os.open(self.path, os.O_WRONLY)
            raise
        if old is not None:
            old.close()
        os.replace(tmp, self.path)
        self._capacity = capacity
        if not final:
            self._fd = os.open(self.path, os.O_WRONLY)

    def _write_static(
        self, f: h5py.File, status: str, wall_time: str, checkpoint: bytes | None
    ) -> None:
        h5md = f.create_group("h5md")
        h5md.attrs["version"] = np.array(H5MD_VERSION, dtype=np.int32)
        h5md.create_group("author").attrs["name"] = _author()
        creator = h5md.create_group("creator")
        creator.attrs["name"] = "rbsim"
        creator.attrs["version"] = _package_version()
        units = h5md.create_group("modules/units")
        units.attrs["version"] = np.array(UNITS_MODULE_VERSION, dtype=np.int32)
        units.attrs["system"] = ascii_attr(UNIT_SYSTEM)
        group = f.create_group("particles/bodies")
        _write_box(group, self.dimension)
        _write_body_table(group, self.bodies)
        if self.fixed is not None:
            fixed = f.create_group("particles/static")
            _write_box(fixed, self.dimension)
            _write_body_table(fixed, self.fixed.bodies)
            set_unit(fixed.create_dataset("position", data=self.fixed.position), "m")
            fixed.create_dataset("orientation", data=self.fixed.orientation)
            if self.fixed.angle is not None:
                set_unit(fixed.create_dataset("angle", data=self.fixed.angle), "rad")
        f.create_group("observables")
        rb = f.create_group("parameters/rbsim")
        for key, value in self.parameters.items():
            rb.create_dataset(key, data=value, dtype=_STR)
        status_ds = rb.create_dataset(
            "status", (), dtype=_fixed(STATUS_BYTES), dcpl=_dcpl(b"", f"S{STATUS_BYTES}")
        )
        status_ds[()] = _status_bytes(status)
        wall_ds = rb.create_dataset(
            "wall_time", (), dtype=_fixed(WALL_TIME_BYTES), dcpl=_dcpl(b"", f"S{WALL_TIME_BYTES}")
        )
        wall_ds[()] = wall_time.encode()
        self._status_offset = status_ds.id.get_offset()
        self._wall_offset = wall_ds.id.get_offset()
        if checkpoint is not None:
            rb.create_dataset("checkpoint", data=np.frombuffer(checkpoint, np.uint8))

    def _write_series(
        self,
        f: h5py.File,
        capacity: int,
        old: h5py.File | None,
        keep: int,
        final: bool,
        stop: Callable[[], bool] | None = None,
    ) -> None:
        bodies = f["particles/bodies"]
        step_ds = time_ds = None
        units = {block_key(name): unit for name, (_c, unit) in self._body_series.items()}
        units |= {"contact_position": "m", "contact_force": "N"}
        for s in self._series:
            shape = ((self._contact_capacity if s.rows else capacity), *s.frame)
            if final:
                kwargs: dict = {}
                if self.compression != "none" and math.prod(shape) > 0:
                    frame_bytes = max(1, s.frame_bytes)
                    rows = max(1, min(CHUNK_MAX_FRAMES, CHUNK_TARGET_BYTES // frame_bytes))
                    kwargs = {
                        "chunks": (min(rows, max(1, capacity)), *(max(1, d) for d in s.frame))
                    }
                    kwargs["compression"] = self.compression
                    if self.compression == "gzip":
                        kwargs["shuffle"] = True
                ds = f.create_dataset(s.path, shape=shape, dtype=s.dtype, **kwargs)
            else:
                fill = -1 if s.key == "step" else (np.nan if s.key == "time" else None)
                ds = f.create_dataset(
                    s.path, shape=shape, dtype=s.dtype, dcpl=_dcpl(fill, s.dtype.str)
                )
                s.offset = ds.id.get_offset() if math.prod(shape) else -1
            if keep and old is not None and math.prod(s.frame) >= 0:
                kept = self.contact_rows_flushed if s.rows else keep
                source = old[s.path]
                # in slices of whole chunks, a stop() asked between them (the final layout
                # of a gzip file takes seconds: a Ctrl-C there stops it, see close)
                rows = ds.chunks[0] * COPY_CHUNKS if ds.chunks else max(kept, 1)
                for first in range(0, kept, rows):
                    if stop is not None and stop():
                        raise LayoutStopped
                    ds[first : first + rows] = source[first : min(first + rows, kept)]
            if s.key == "step":
                step_ds = ds
            elif s.key == "time":
                time_ds = ds
            elif s.key in units and units[s.key] is not None:
                set_unit(ds, units[s.key])
            elif s.path.startswith("observables/") and s.key in OBSERVABLE_UNITS:
                set_unit(ds, OBSERVABLE_UNITS[s.key])
        assert step_ds is not None and time_ds is not None
        set_unit(time_ds, "s")
        for name in self._body_series:
            group = bodies[name]
            if name != "position":
                group["step"], group["time"] = step_ds, time_ds  # hard links
        for name in self._spec or {}:
            group = f[f"observables/{name}"]
            group["step"], group["time"] = step_ds, time_ds
        if self.contacts:
            for name in ("start", "count"):
                group = f[f"contacts/{name}"]
                group["step"], group["time"] = step_ds, time_ds

    # -- frames ---------------------------------------------------------------------------

    def _block_rows(self) -> int:
        per_body = sum(max(1, c) for c, _unit in self._body_series.values())
        frame_bytes = 8 * self._block_n * per_body + 64
        return max(1, min(BLOCK_MAX_FRAMES, BLOCK_BYTES // frame_bytes))

    @property
    def block(self) -> dict[str, np.ndarray]:
        """The block that frames are gathered in: step (B,) int64, time (B,) s, position,
        orientation, velocity (B,M,2), angle, angular_velocity (B,M) float64 for the M
        rows of an appended frame (3D: position, velocity, angular_velocity and
        body_angular_momentum (B,M,3), orientation (B,M,4)), and each observable
        (B, *shape). With contacts: contact_start, contact_points (B,) int64 (each
        frame's first row in the contact rows and its number of points), and the contact
        rows, contact_body (C,2) int64, contact_position, contact_normal (C,D),
        contact_force (C,) float64, room that grow_contact_rows enlarges. Fill rows from
        `rows` on, then `commit` them."""
        if self._block is None:
            if self._spec is None:
                raise ValueError("the observables are not known yet: append a frame first")
            b, m = self._block_rows(), self._block_n
            block = {"step": np.full(b, -1, np.int64), "time": np.zeros(b)}
            for name, (components, _unit) in self._body_series.items():
                block[block_key(name)] = np.zeros((b, m, components) if components else (b, m))
            for name, (shape, dtype) in self._spec.items():
                kind = "i8" if np.dtype(dtype).kind in "iub" else "f8"
                block[name] = np.zeros((b, *shape), dtype=kind)
            if self.contacts:
                c, d = CONTACT_BLOCK_ROWS * b, self.dimension
                block["contact_start"] = np.zeros(b, np.int64)
                block["contact_points"] = np.zeros(b, np.int64)
                block["contact_body"] = np.zeros((c, 2), np.int64)
                block["contact_position"] = np.zeros((c, d))
                block["contact_normal"] = np.zeros((c, d))
                block["contact_force"] = np.zeros(c)
            self._block = block
        return self._block

    @property
    def rows(self) -> int:
        """Frames gathered in the block so far."""
        return self._rows

    @property
    def rows_free(self) -> int:
        """Frames the block has room for."""
        return len(self.block["step"]) - self._rows

    def commit(self, rows: int, write_when_full: bool = True) -> None:
        """Count `rows` more frames as filled in the block; writes the block out when it
        is full (unless not `write_when_full`: the caller then flushes)."""
        if self._closed:
            raise ValueError(f"append to a closed trajectory ({self.path})")
        if rows < 0 or rows > self.rows_free:
            raise ValueError(f"commit of {rows} rows with {self.rows_free} free")
        if rows:
            self._last_step = int(self.block["step"][self._rows + rows - 1])
        self._rows += rows
        self.frames_written += rows
        if self.rows_free == 0 and write_when_full:
            self._write_block()

    def append(
        self,
        step: int,
        time: float,
        position: np.ndarray,
        orientation: np.ndarray,
        angle: np.ndarray | None,
        velocity: np.ndarray,
        angular_velocity: np.ndarray,
        observables: dict[str, float | np.ndarray],
        angular_momentum: np.ndarray | None = None,
    ) -> None:
        """Append one frame; written out with its block, and flushed when `flush_seconds`
        have passed since the last flush.

        step: step number; time: s. position (M,2) m, body origin; orientation (M,2)
        (cos θ, sin θ); angle (M,) rad, unwrapped; velocity (M,2) m/s of the centre of
        mass; angular_velocity (M,) rad/s (M = block_bodies). In 3D: position, velocity,
        angular_velocity (world frame) and angular_momentum (kg m²/s, world frame about
        each COM) (M,3), orientation (M,4) (w, x, y, z), angle None. observables: name ->
        scalar or (k,) array; the first frame fixes the names unless the writer was told.
        """
        if self._closed:
            raise ValueError(f"append to a closed trajectory ({self.path})")
        if self._spec is None:
            spec = {}
            for name, value in observables.items():
                arr = np.asarray(value)
                if arr.ndim > 1:
                    raise ValueError(
                        f"observable {name!r} must be a scalar or 1-D, got {arr.shape}"
                    )
                integral = arr.dtype.kind in "iub" and name not in OBSERVABLE_UNITS
                spec[name] = (arr.shape, "i8" if integral else "f8")
            self._spec = spec
            self._layout(self._capacity, keep_from=None, series=True)
        elif observables.keys() != self._spec.keys():
            missing = sorted(self._spec.keys() - observables.keys())
            extra = sorted(observables.keys() - self._spec.keys())
            raise ValueError(
                f"observables must be those of the first frame: missing {missing}, "
                f"unexpected {extra}"
            )
        block, r = self.block, self._rows
        given = {
            "position": position,
            "orientation": orientation,
            "angle": angle,
            "velocity": velocity,
            "angular_velocity": angular_velocity,
            "angular_momentum": angular_momentum,
        }
        values = {block_key(name): given[name] for name in self._body_series}
        for name, value in values.items():
            if value is None:
                raise ValueError(f"{name}: a {self.dimension}D frame needs it")
        values.update(observables)
        for key, value in values.items():
            target = block[key]
            if np.shape(value) != target.shape[1:]:
                raise ValueError(
                    f"{key}: frame has shape {np.shape(value)}, expected {target.shape[1:]}"
                )
            if target.dtype.kind == "i":
                arr = np.asarray(value)
                if np.any(arr.astype(np.int64) != arr):
                    raise ValueError(f"{key}: {value!r} is not an integer, as in the first frame")
        for key, value in values.items():
            block[key][r] = value
        block["step"][r] = step
        block["time"][r] = time
        self.commit(1)
        if self.flush_due():
            self.flush()

    def flush_due(self) -> bool:
        """Whether `flush_seconds` have passed since the last flush."""
        return _time.monotonic() - self._last_flush >= self.flush_seconds

    def _write_block(self) -> None:
        """Write the block's frames to the file (in place, `step` last) and empty it."""
        rows = self._rows
        if rows == 0:
            return
        t0 = self.frames_flushed
        block = self.block
        c0 = self.contact_rows_flushed
        used = 0  # contact rows of the block's frames
        if self.contacts:
            used = int(block["contact_start"][rows - 1] + block["contact_points"][rows - 1])
        grow_frames = t0 + rows > self._capacity
        if grow_frames and self._frames_total is not None and t0 + rows > self._frames_total:
            raise ValueError(
                f"{self.path}: more frames than the {self._frames_total} the writer was told"
            )
        if grow_frames or c0 + used > self._contact_capacity:
            capacity = self._capacity
            if grow_frames:  # (a run asks make_room before it steps: this is append's)
                capacity = max(2 * self._capacity, t0 + rows)
                if self._frames_total is not None:
                    capacity = min(capacity, self._frames_total)
            if c0 + used > self._contact_capacity:
                # room for the rest of the run at the rate so far, and at least twice as much
                rate = (c0 + used) / (t0 + rows)
                estimate = math.ceil(1.25 * rate * capacity)
                self._contact_capacity = max(2 * self._contact_capacity, c0 + used, estimate)
            self._layout(capacity, keep_from=self.path, series=True)
        assert self._fd is not None
        for s in self._series:
            if s.offset < 0:
                continue
            if s.rows:
                data = block[s.key][:used]
                if s.key == "contact_body" and self._contact_map is not None:
                    data = self._contact_map[data]
                at = c0
            else:
                data = block[s.key][:rows]
                if self._select is not None and s.key in self._body_keys:
                    data = data[:, self._select]
                if s.key == "orientation" and self.dimension == 3:
                    data = self._continuous(data)
                if s.key == "contact_start":
                    data = data + c0  # rows of the file, not of the block
                at = t0
            data = np.ascontiguousarray(data, dtype=s.dtype)
            _pwrite_all(self._fd, data, s.offset + at * s.frame_bytes, self.path)
        self._rows = 0
        self.frames_flushed = t0 + rows
        self.contact_rows_flushed = c0 + used

    def _continuous(self, q: np.ndarray) -> np.ndarray:
        """Quaternion frames (rows, M, 4) with the sign of each made continuous: a row's
        q is negated where its dot product with the previous written q is negative (q
        and -q are one rotation). Returns a new array; remembers the last row."""
        q = np.array(q, np.float64)
        if not len(q):
            return q
        prev = np.concatenate([q[:1] if self._last_q is None else self._last_q[None], q[:-1]])
        dots = np.einsum("rij,rij->ri", q, prev)  # with the previous row as the engine held it
        if np.any(dots == 0.0):
            # a half turn between two frames exactly: the rule restarts there (+1), which
            # a running product of signs does not express; row by row
            last = self._last_q
            for r in range(len(q)):
                if last is not None:
                    flip = np.einsum("ij,ij->i", q[r], last) < 0.0
                    q[r, flip] = -q[r, flip]
                last = q[r]
        else:
            # the written sign flips where the held one turned against the previous row
            # (row 0 against the last written row: its sign is the written one already)
            sign = np.cumprod(np.where(dots < 0.0, -1.0, 1.0), axis=0)
            q *= sign[..., None]
        self._last_q = q[-1].copy()
        return q

    def write_block(self) -> None:
        """Write the block's frames to the file now (a full block), without a
        checkpoint: the flush clock (`flush_due`) runs on."""
        if not self._closed:
            self._write_block()

    def flush(
        self,
        checkpoint: bytes | None = None,
        step: int | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> None:
        """Write every gathered frame to the file now, and `checkpoint` (the engine's
        state at `step`, default the last frame's, bytes) beside it for `rbsim run
        --resume`; the frames on file must be those up to that state. A true stop()
        drops the checkpoint's write midway (write_checkpoint); the last one stays."""
        if self._closed:
            return
        self._write_block()
        self._write_wall(self._wall_now())
        if checkpoint is not None and self.frames_flushed:
            at = self._last_step if step is None else int(step)
            owner = self.parameters.get(TRAJECTORY_ID, "")
            write_checkpoint(self.checkpoint_path, self.frames_flushed, at, checkpoint, stop, owner)
        self._last_flush = _time.monotonic()

    def close(
        self,
        *,
        status: str = "complete",
        wall_time: float | None = None,
        checkpoint: bytes | None = None,
        checkpoint_step: int | None = None,
        keep_sidecar: bool = False,
        stop: Callable[[], bool] | None = None,
    ) -> None:
        """Write the last frames, record `status` and `wall_time`, and close. Idempotent.

        status: "complete", "interrupted" (Ctrl-C, SIGTERM) or "failed", optionally with
            a detail after a colon; stored up to STATUS_BYTES bytes of UTF-8.
        wall_time: s of this segment; by default the time since `started`, read once
            the file is written (a compressed file's final layout included). The file
            records wall_before + wall_time, also left in self.wall_time.
        checkpoint: the engine's state at step `checkpoint_step` (default the last
            frame's), every frame up to it written; stored in the file, or beside it
            (below), so that a run that did not complete can be resumed from it.
        keep_sidecar: leave the checkpoint file of the last flush beside the trajectory
            (a run stopped with no checkpoint of its last frame resumes from that one).
        A file with room for more frames than it holds, or asked to be compressed, is laid
        out anew with exactly its frames; a true stop() during that (a Ctrl-C in the
        seconds a large file takes to compress) leaves the file as it was, every frame
        in it, with status "interrupted" and the checkpoint beside it (`checkpoint`, else
        the last flush's: `rbsim run --resume` finishes it), and raises LayoutStopped.
        A run that did not complete, with more than STOP_COPY_BYTES of frames on file, is
        closed in place as that (its room and its frames as they are, `checkpoint` beside
        it), without a copy: a stopped run ends within a second however large its file.
        """
        if self._closed:
            return
        measured = wall_time is None
        if wall_time is None:
            wall_time = _time.perf_counter() - self._started
        try:
            if self._spec is None:  # no frame appended: lay out the standard series
                self._spec = dict(OBSERVABLES)
                self._layout(self._capacity, keep_from=None, series=True)
            self._write_block()
            wall = repr(self.wall_before + float(wall_time))
            exact = self.frames_flushed == self._capacity
            exact = exact and self.contact_rows_flushed == self._contact_capacity
            in_place = exact and self.compression == "none" and checkpoint is None
            large = self._frames_bytes() > STOP_COPY_BYTES
            if in_place or (status != "complete" and large):
                self._close_in_place(status, checkpoint, checkpoint_step)
                keep_sidecar = keep_sidecar or checkpoint is not None
                if measured:
                    wall = repr(self._wall_now())
                self._write_wall(float(wall))
            else:
                try:
                    self._layout(
                        self.frames_flushed,
                        keep_from=self.path,
                        series=True,
                        final=True,
                        status=status,
                        wall_time=wall,
                        checkpoint=checkpoint,
                        stop=stop,
                    )
                except LayoutStopped:
                    # the file at path keeps every frame, laid out as during the run:
                    # marked interrupted, the checkpoint beside it (this one, else the
                    # last flush's: the raise passes its removal below)
                    self._close_in_place(STATUS_INTERRUPTED, checkpoint, checkpoint_step)
                    self._write_wall(self._wall_now())
                    raise
                if measured:  # the final layout's time included (gzip: most of it)
                    wall = repr(self._wall_now())
                    self._fd = os.open(self.path, os.O_WRONLY)
                    self._write_wall(float(wall))
            self.wall_time = float(wall)
        finally:
            self._closed = True
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None
        if not keep_sidecar:
            with contextlib.suppress(OSError):
                os.unlink(self.checkpoint_path)

    def _frames_bytes(self) -> int:
        """Bytes of the frames (and contact rows) on file: what a final layout copies."""
        if not self._series:
            return 0
        rows = sum(s.frame_bytes for s in self._series if s.rows)
        frames = sum(s.frame_bytes for s in self._series if not s.rows)
        return self.frames_flushed * frames + self.contact_rows_flushed * rows

    def _close_in_place(
        self, status: str, checkpoint: bytes | None, checkpoint_step: int | None
    ) -> None:
        """Close the file as it is laid out (its room kept: unwritten rows read step -1):
        `checkpoint` (if any) written beside it for --resume, then `status` in place."""
        if checkpoint is not None and self.frames_flushed:
            at = self._last_step if checkpoint_step is None else int(checkpoint_step)
            owner = self.parameters.get(TRAJECTORY_ID, "")
            write_checkpoint(self.checkpoint_path, self.frames_flushed, at, checkpoint, None, owner)
        if self._fd is None:
            self._fd = os.open(self.path, os.O_WRONLY)
        self._write_status(status)

    def _wall_now(self) -> float:
        """The run's wall time so far, s: earlier segments and this one."""
        return self.wall_before + (_time.perf_counter() - self._started)

    def _write_status(self, status: str) -> None:
        """Write `status` over the file's status, in place (its fixed bytes), through the
        open descriptor."""
        data = np.frombuffer(_status_bytes(status), np.uint8)
        _pwrite_all(self._fd, data, self._status_offset, self.path)

    def _write_wall(self, seconds: float) -> None:
        """Write `seconds` over the file's wall_time, in place (its fixed bytes)."""
        if self._fd is None or self._wall_offset < 0:
            return
        wall = repr(float(seconds)).encode().ljust(WALL_TIME_BYTES, b"\0")[:WALL_TIME_BYTES]
        _pwrite_all(self._fd, np.frombuffer(wall, np.uint8), self._wall_offset, self.path)

    def abandon(self, status: str | None = None) -> bool:
        """Close the file descriptor without writing anything more (after an I/O error):
        the file keeps what was flushed, and the checkpoint beside it stays. With
        `status` ("failed: ..."), that status is written over the file's, in place (its
        bytes are on disk already: a full disk has room for it), best effort. Returns
        whether the file now records `status`."""
        self._closed = True
        marked = False
        if status is not None and self._status_offset >= 0:  # a file laid out at `path`
            with contextlib.suppress(OSError):
                if self._fd is None:
                    self._fd = os.open(self.path, os.O_WRONLY)
                self._write_status(status)
                os.fsync(self._fd)
                marked = True
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = None
        return marked

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


def _status_bytes(status: str) -> bytes:
    text = str(status).encode("utf-8")[:STATUS_BYTES]
    text = text.decode("utf-8", errors="ignore").encode("utf-8")
    return text.ljust(STATUS_BYTES, b"\0")


def _pwrite_all(fd: int, data: np.ndarray, offset: int, path: str) -> None:
    """Write all of data's bytes at offset (os.pwrite may write fewer)."""
    if data.size == 0:  # a frame block without contact points, say
        return
    view = memoryview(np.ascontiguousarray(data)).cast("B")
    while len(view):
        n = os.pwrite(fd, view, offset)
        if n <= 0:
            raise OSError(f"{path}: short write")
        view = view[n:]
        offset += n


# ---------------------------------------------------------------------------------------
# Reader
# ---------------------------------------------------------------------------------------


@dataclass
class ContactPoints:
    """The contact points of T frames (output.contacts: points), C rows in all.

    start, count: (T,) int64, frame t's points are rows start[t] .. start[t] + count[t].
    body: (C,2) int32, the two bodies of each point: a row of the trajectory's bodies,
        or len(bodies) + a row of its fixed (static, stored once) bodies; -1 for a body
        the file does not hold. position: (C,D) m, world frame, where the two bodies meet
        at the frame's time. normal: (C,D) unit, from the first body towards the second
        (the direction the second is pushed). force: (C,) N, the point's mean normal
        force over the step (every push it made in the step, the shock pass's and a
        bounce's too, over dt).
    """

    start: np.ndarray
    count: np.ndarray
    body: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    force: np.ndarray

    def frame(self, t: int) -> slice:
        """The rows of frame `t` (index the row arrays with it)."""
        a = int(self.start[t])
        return slice(a, a + int(self.count[t]))


def read_contacts(f: h5py.File, t: int) -> ContactPoints | None:
    """The contact points of the first `t` frames of an open file (None when the run
    did not record them)."""
    if "contacts/start" not in f:
        return None
    g = f["contacts"]
    start, count = g["start/value"][:t], g["count/value"][:t]
    used = int(start[-1] + count[-1]) if t else 0
    rows = {name: g[name][:used] for name in CONTACT_ROW_SERIES}
    return ContactPoints(start=start, count=count, **rows)


@dataclass
class Trajectory:
    """A trajectory file in memory: T frames of N bodies in a world of `dimension` D.

    step (T,) int64; time (T,) s; position (T,N,D) m, body origin; orientation (T,N,2)
    (cos θ, sin θ) in 2D, (T,N,4) (w, x, y, z) in 3D, sign continuous from frame to
    frame; angle (T,N) rad, unwrapped (2D; None in 3D); velocity (T,N,D) m/s, centre of
    mass; angular_velocity (T,N) rad/s (2D) or (T,N,3) world frame (3D);
    angular_momentum (T,N,3) kg m²/s, world frame about each centre of mass (3D; None in
    2D); observables name -> (T,) or (T,k) (energies J, linear momentum kg m/s, angular
    momentum kg m²/s about the world origin (T,) in 2D, (T,3) in 3D, contact count);
    bodies: static data; parameters: /parameters/rbsim as strings; engine: "rbsim",
    "pymunk", ...; status: "complete", "interrupted", "failed", or "running" (writer
    running or killed); fixed: the static bodies stored once rather than per frame
    (output.bodies), or None; contacts: each frame's contact points (ContactPoints), or
    None when the run did not record them (output.contacts).
    """

    step: np.ndarray
    time: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    angle: np.ndarray | None
    velocity: np.ndarray
    angular_velocity: np.ndarray
    observables: dict[str, np.ndarray]
    bodies: BodyTable
    parameters: dict[str, str]
    engine: str
    status: str
    fixed: FixedBodies | None = None
    dimension: int = 2
    angular_momentum: np.ndarray | None = None
    contacts: ContactPoints | None = None
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


class TrajectoryError(OSError):
    """A file that is not a readable rbsim trajectory: missing, truncated or corrupt."""


def open_for_reading(path: str | os.PathLike) -> h5py.File:
    """Open a trajectory read-only; raises TrajectoryError (at once) with what is wrong.

    Files of this rbsim open as they are at any moment, even while being written or
    after the writer was killed. Files of earlier versions (written in SWMR mode) that
    were left open by a killed writer are opened in SWMR read mode."""
    path = os.fspath(path)
    try:
        return h5py.File(path, "r")
    except FileNotFoundError:
        raise TrajectoryError(f"{path}: no such file") from None
    except OSError as err:
        text = str(err)
        if "already open for write" in text or "file close degree" in text:
            try:
                return h5py.File(path, "r", swmr=True)
            except OSError:
                pass
        if not h5py.is_hdf5(path):
            raise TrajectoryError(f"{path}: {NOT_HDF5}") from None
        sizes = _TRUNCATED_RE.search(text)
        if sizes:
            have, size = int(sizes[1]), int(sizes[2])
            raise TrajectoryError(
                f"{path}: the file is truncated: {have:,} of its {size:,} bytes are there "
                "(a copy cut short, or a disk that filled)"
            ) from None
        raise TrajectoryError(f"{path}: {_damaged(err)}") from None


# The one wording of each way a file is not a readable rbsim trajectory (`rbsim info`,
# `render`, `plot`, load_trajectory)
NOT_HDF5 = "not an HDF5 file (rbsim writes .h5 trajectories)"
NOT_RBSIM = (
    "not an rbsim trajectory: an HDF5 file without /particles/bodies (written by another program?)"
)
_TRUNCATED_RE = re.compile(r"truncated file: eof = (\d+).*stored_eof = (\d+)")
# h5py's wrapping of HDF5's reason: "Unable to synchronously open object (reason)"
_H5_REASON_RE = re.compile(r"^'?Unable to [^(]*\((.*)\)'?$", re.S)


def _damaged(err: BaseException) -> str:
    """The message for a file whose HDF5 structure cannot be read: HDF5's own reason
    (without h5py's wrapping)."""
    text = str(err)
    match = _H5_REASON_RE.match(text)
    return f"a damaged rbsim trajectory: HDF5 cannot read it ({match[1] if match else text})"


def unreadable(path: str | os.PathLike, err: BaseException) -> TrajectoryError:
    """The TrajectoryError for `err`, met reading the file at `path`: `err` itself when it
    is one, else the file is damaged (with HDF5's reason)."""
    if isinstance(err, TrajectoryError):
        return err
    return TrajectoryError(f"{os.fspath(path)}: {_damaged(err)}")


def check_rbsim(f: h5py.File, path: str | os.PathLike) -> None:
    """Raise TrajectoryError (NOT_RBSIM) when the open file `f` is not rbsim's layout."""
    try:
        ours = isinstance(f.get("particles/bodies"), h5py.Group)
    except READ_ERRORS as err:
        raise unreadable(path, err) from None
    if not ours:
        raise TrajectoryError(f"{os.fspath(path)}: {NOT_RBSIM}")


# What h5py raises on a file whose structure is damaged, besides OSError, KeyError and
# ValueError: RuntimeError (a corrupt B-tree), IndexError, AttributeError (an object of
# another kind where a dataset belongs).
DAMAGED = (RuntimeError, IndexError, AttributeError)
# Everything reading a damaged file may raise.
READ_ERRORS = (OSError, KeyError, ValueError, TypeError, *DAMAGED)


@contextlib.contextmanager
def reading(path: str | os.PathLike) -> Iterator[h5py.File]:
    """open_for_reading as a context, with every error met while reading the file turned
    into a TrajectoryError naming it (`unreadable`): a damaged file fails at once with
    what is wrong, never with a traceback; an HDF5 file of another program, as such."""
    path = os.fspath(path)
    with open_for_reading(path) as f:
        check_rbsim(f, path)
        try:
            yield f
        except READ_ERRORS as err:
            raise unreadable(path, err) from None


def _series_groups(f: h5py.File) -> tuple[list[str], list[str]]:
    """Paths of the body and observable time series groups present in the file."""
    bodies = [f"particles/bodies/{n}" for n in ALL_BODY_SERIES if f"particles/bodies/{n}" in f]
    obs = [f"observables/{n}" for n in f["observables"]] if "observables" in f else []
    return bodies, obs


def frame_count(f: h5py.File, closed: bool) -> int:
    """Frames present in every time series: the leading frames whose step was written
    (>= 0: rows with room made but not yet written hold -1), within the shortest series.
    `closed` (the writer closed the file) is kept for callers; every file reads alike."""
    if "particles/bodies/position" not in f:
        return 0
    body_groups, obs_groups = _series_groups(f)
    contact_groups = [g for g in ("contacts/start", "contacts/count") if g in f]
    values = [f[g]["value"] for g in body_groups + obs_groups + contact_groups]
    step, time = f["particles/bodies/position/step"], f["particles/bodies/position/time"]
    t = min(ds.shape[0] for ds in [*values, step, time])
    unwritten = np.flatnonzero(step[:t] < 0)
    return int(unwritten[0]) if unwritten.size else t


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


def read_fixed(f: h5py.File) -> FixedBodies | None:
    """The static bodies an open file stores once (/particles/static), or None."""
    if "particles/static" not in f:
        return None
    g = f["particles/static"]
    return FixedBodies(
        bodies=read_body_table(g),
        position=g["position"][()],
        orientation=g["orientation"][()],
        angle=g["angle"][()] if "angle" in g else None,
    )


def load_trajectory(path: str | os.PathLike) -> Trajectory:
    """Read a trajectory file written by TrajectoryWriter (closed normally, still being
    written, or left by a killed writer). Every series is cut to the frames present in
    all of them. Units as in `Trajectory`. Raises TrajectoryError (at once) for a file
    that is missing, truncated, damaged or not an rbsim trajectory."""
    with reading(path) as f:
        bodies = read_body_table(f["particles/bodies"])
        n, dimension = len(bodies), bodies.dimension
        params = read_parameters(f)
        t = frame_count(f, closed=params.get("status", STATUS_RUNNING) != STATUS_RUNNING)
        arrays: dict[str, np.ndarray | None] = {"angle": None, "angular_momentum": None}
        for name, (components, _unit) in body_series(dimension).items():
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
        fixed = read_fixed(f)
        contacts = read_contacts(f, t)
    return Trajectory(
        step=step,
        time=time,
        observables=observables,
        bodies=bodies,
        parameters=params,
        engine=params.get("engine", "unknown"),
        status=params.get("status", "unknown"),
        fixed=fixed,
        dimension=dimension,
        contacts=contacts,
        **arrays,
    )


@dataclass
class Frames:
    """Some series of a trajectory file (`load_frames`), cut like load_trajectory's to
    the frames present in every series of the file: step (T,); series name -> (T,N,...)
    array (units as in Trajectory); observables name -> (T,...) array; status and
    wall_time (s, None when not recorded) of /parameters/rbsim; dimension 2 or 3; fixed:
    the static bodies stored once (output.bodies), or None."""

    step: np.ndarray
    series: dict[str, np.ndarray]
    observables: dict[str, np.ndarray]
    status: str
    wall_time: float | None
    dimension: int
    fixed: FixedBodies | None


def load_frames(
    path: str | os.PathLike, series: Sequence[str], observables: Sequence[str] = ()
) -> Frames:
    """Read only the named per-body series ("position", "velocity", ...) and observables
    of a trajectory file, with its step, status and wall time: what load_trajectory
    would give of them, for a fraction of its reads. A series the file lacks is
    (0,N,...) as in load_trajectory; an observable it lacks is left out."""
    with reading(path) as f:
        group = f["parameters/rbsim"] if "parameters/rbsim" in f else {}
        text = {}
        for key in ("status", "wall_time"):
            value = group[key][()] if key in group else b""
            text[key] = (
                value.decode("utf-8").rstrip("\x00") if isinstance(value, bytes) else str(value)
            )
        status = text["status"] or "unknown"
        try:
            wall_time: float | None = float(text["wall_time"])
        except ValueError:
            wall_time = None
        bodies = f["particles/bodies"]
        dimension = _read_dimension(bodies)
        n = len(bodies["name"])
        t = frame_count(f, closed=status != STATUS_RUNNING)
        got: dict[str, np.ndarray] = {}
        for name in series:
            components = body_series(dimension)[name][0]
            key = f"particles/bodies/{name}/value"
            empty = (0, n, components) if components else (0, n)
            got[name] = f[key][:t] if t and key in f else np.zeros(empty)
        step = f["particles/bodies/position/step"][:t] if t else np.zeros(0, np.int64)
        obs = {k: f[f"observables/{k}/value"][:t] for k in observables if f"observables/{k}" in f}
        fixed = read_fixed(f)
    return Frames(step, got, obs, status, wall_time, dimension, fixed)


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


# What a solver setting left unset (None) in the file means, for `rbsim info`
SOLVER_DEFAULT_WORDS = {
    "threads": (
        "not set (the cores the process may run on, each step on one thread or on all as the "
        "run timed them; 1 in batch and sweep workers)"
    )
}


def summarize(path: str | os.PathLike) -> str:
    """The text `rbsim info OUT.h5` prints: engine, status, scene name, bodies by type,
    frames, step and time range (s), dt (s), wall time (s), file size, observables at
    the first and last frame, and the solver parameters. Reads only what it prints.
    Raises TrajectoryError as load_trajectory does."""
    path = os.fspath(path)
    with reading(path) as f:
        params = read_parameters(f)
        dimension = _read_dimension(f["particles/bodies"])
        types = _read_strings(f["particles/bodies/type"])
        fixed = len(f["particles/static/name"]) if "particles/static/name" in f else 0
        t = frame_count(f, closed=params.get("status", STATUS_RUNNING) != STATUS_RUNNING)
        step = time = np.zeros(0)
        if t:
            step = f["particles/bodies/position/step"][[0, t - 1] if t > 1 else [0]]
            time = f["particles/bodies/position/time"][[0, t - 1] if t > 1 else [0]]
        first_last: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
        for group in _series_groups(f)[1] if t else []:
            ds = f[group]["value"]
            unit = ds.attrs.get("unit", "")
            first_last[group.split("/", 1)[1]] = (ds[0], ds[t - 1], attr_text(unit))
        creator_version = str(f["h5md/creator"].attrs.get("version", "?"))
        contact_line = None
        if "contacts/start" in f:
            count = f["contacts/count/value"][:t]
            used = int(f["contacts/start/value"][t - 1] + count[-1]) if t else 0
            contact_line = f"  contacts   {counted(used, 'point')} over {counted(t, 'frame')}"
            if used:
                busiest = int(np.argmax(count))
                force = float(np.max(f["contacts/force"][:used]))
                contact_line += (
                    f", at most {int(count[busiest])} in a frame "
                    f"(step {int(f['particles/bodies/position/step'][busiest])}), "
                    f"force up to {force:.6g} N"
                )
        series = []
        for group in _series_groups(f)[0]:
            shape = f[group]["value"].shape[1:]
            dims = ",".join(["T", "N", *(str(k) for k in shape[1:])])
            series.append(f"{group.rsplit('/', 1)[1]} ({dims})")

    lines = [f"rbsim trajectory {path} ({_human_bytes(os.path.getsize(path))})"]
    version = params.get("rbsim_version", creator_version)
    lines.append(f"  engine     {params.get('engine', 'unknown')} (rbsim {version})")
    status = params.get("status", "unknown")
    if status == STATUS_RUNNING:
        status += " (not closed: the writer is still running or was killed)"
    lines.append(f"  status     {status}")
    lines.append(f"  scene      {scene_name(params, path)}")
    lines.append(f"  dimension  {dimension}")
    counts = ", ".join(f"{types.count(k)} {k}" for k in BODY_TYPES if types.count(k))
    lines.append(f"  bodies     {len(types)}" + (f" ({counts})" if counts else ""))
    if fixed:
        lines[-1] += f"; and {fixed} static stored once (output.bodies)"
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
    if series:
        lines.append(f"  series     {', '.join(series)}")
    if contact_line is not None:
        lines.append(contact_line)
    try:
        wall = float(params.get("wall_time", ""))
    except ValueError:
        lines.append("  wall time  ?")
    else:
        # the whole run, reading the scene and building the engine included: `rbsim
        # run`'s summary gives the stepping's own time and rate apart
        rate = ""
        if t > 1 and wall > 0:
            rate = f", {float(step[-1] - step[0]) / wall:.4g} steps/s overall"
        resumed = params.get("resumed", "0")
        resumed = int(resumed) if resumed.isdigit() else 0
        if resumed:  # the sum over the segments (a killed one's: to its last flush)
            rate += f"; the sum of its {resumed + 1} segments, resumed {counted(resumed, 'time')}"
        lines.append(f"  wall time  {wall:.3f} s (the whole run, set-up included{rate})")

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
            shown = {
                k: SOLVER_DEFAULT_WORDS.get(k, v) if v is None else v for k, v in solver.items()
            }
            lines += [f"    {str(k).ljust(width)}  {v}" for k, v in shown.items()]
        else:
            lines += [f"    {line}" for line in solver_text.splitlines()]
    return "\n".join(lines)
