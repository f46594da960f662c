"""`rbsim plot`: energy and momentum over time, for one or several trajectories on the
same axes (matplotlib, the optional `plot` extra).

Reads only the observables (T scalars or vectors per file), never the body series.
Units: time s, energy J, linear momentum kg m/s, angular momentum kg m²/s.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..io.trajectory import READ_ERRORS, frame_count, read_parameters, reading, unreadable
from .render import RenderError, need_matplotlib

__all__ = ["Observables", "plot_lines", "plot_observables", "read_observables"]

# Energies, with their line style; the colour is the file's.
ENERGIES = (
    ("kinetic_energy", "kinetic", ":"),
    ("potential_energy", "potential", "--"),
    ("total_energy", "total", "-"),
)


@dataclass
class Observables:
    """The observables of one trajectory: time (T,) s, and name -> (T,) or (T,k)
    (energies J, linear_momentum (T,2) or (T,3) kg m/s, angular_momentum (T,) or
    (T,3) kg m²/s), with
    total_energy = kinetic + potential added when the file has both."""

    path: str
    label: str
    time: np.ndarray
    values: dict[str, np.ndarray]


def read_observables(path: str | os.PathLike) -> Observables:
    """Read the observables of a trajectory file (either engine). Raises RenderError
    naming the file when it is not an rbsim trajectory."""
    path = os.fspath(path)
    try:
        with reading(path) as f:  # a damaged file: TrajectoryError, an OSError
            params = read_parameters(f)
            t = frame_count(f, closed=params.get("status", "running") != "running")
            time = np.asarray(f["particles/bodies/position/time"][:t], dtype=float)
            values = {
                name: np.asarray(f[f"observables/{name}/value"][:t], dtype=float)
                for name in f.get("observables", {})
            }
    except READ_ERRORS as err:  # worded as by `rbsim info`
        raise RenderError(str(unreadable(path, err))) from None
    if "kinetic_energy" in values and "potential_energy" in values:
        values.setdefault("total_energy", values["kinetic_energy"] + values["potential_energy"])
    engine = params.get("engine", "unknown")
    return Observables(path, f"{os.path.basename(path)} ({engine})", time, values)


# Line styles of the x, y and z components of a vector series.
COMPONENTS = (("x", "-"), ("y", "--"), ("z", "-."))


def plot_lines(obs: Observables) -> list[tuple[int, str, str, np.ndarray]]:
    """The lines `plot_observables` draws for one trajectory: (panel, label, line style,
    (T,) values), panel 0 energies (J), 1 linear momentum (kg m/s), 2 angular momentum
    (kg m²/s). Vector series give one line per component: px, py (and pz in 3D); L in
    2D, Lx, Ly, Lz in 3D."""
    lines: list[tuple[int, str, str, np.ndarray]] = []
    for name, what, style in ENERGIES:
        if name in obs.values:
            lines.append((0, what, style, obs.values[name]))
    p = obs.values.get("linear_momentum")
    if p is not None and p.ndim == 2:
        for j, (axis, style) in enumerate(COMPONENTS[: p.shape[1]]):
            lines.append((1, f"p{axis}", style, p[:, j]))
    ang = obs.values.get("angular_momentum")
    if ang is not None and ang.ndim == 1:
        lines.append((2, "L", "-", ang))
    elif ang is not None and ang.ndim == 2:
        for j, (axis, style) in enumerate(COMPONENTS[: ang.shape[1]]):
            lines.append((2, f"L{axis}", style, ang[:, j]))
    return lines


def panel_titles(data: list[Observables]) -> tuple[str, str, str]:
    """The titles of `plot_observables`' three panels for the trajectories `data`: what
    each line style means, naming z only where a trajectory has a z component."""
    styles = {"-": "solid", "--": "dashed", "-.": "dash-dot"}

    def components(name: str) -> str:
        n = max((obs.values[name].shape[1] for obs in data if _vector(obs, name)), default=0)
        return ", ".join(f"{axis} ({styles[style]})" for axis, style in COMPONENTS[:n])

    energy = "kinetic (dotted), potential (dashed), total (solid)"
    angular = components("angular_momentum")
    return energy, components("linear_momentum"), angular and f"about the world origin: {angular}"


def _vector(obs: Observables, name: str) -> bool:
    """Whether `obs` holds the series `name` as (T, components)."""
    return name in obs.values and obs.values[name].ndim == 2


def plot_observables(
    paths: list[str | os.PathLike], output: str | os.PathLike, *, size: tuple[float, float] = (8, 8)
) -> list[Observables]:
    """Plot kinetic, potential and total energy (J), linear momentum x and y, and z in
    3D (kg m/s), and angular momentum (kg m²/s; its three components in 3D) against
    time (s) for every trajectory in `paths`, one colour per file, into `output`
    (format from its suffix: .png, .pdf, .svg).
    size: inches. Returns what was read. Raises RenderError."""
    need_matplotlib("rbsim plot")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    data = [read_observables(p) for p in paths]
    for obs in data:
        if not len(obs.time):
            raise RenderError(f"{obs.path}: no frames to plot")
        if not obs.values:
            raise RenderError(f"{obs.path}: no observables to plot")
    fig = Figure(figsize=size, dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, 1, sharex=True)
    ax_e, ax_p, ax_l = axes
    colours = [f"C{i}" for i in range(10)]
    for i, obs in enumerate(data):
        colour = colours[i % len(colours)]
        for panel, label, style, values in plot_lines(obs):
            axes[panel].plot(obs.time, values, style, color=colour, label=f"{label}, {obs.label}")
    ax_e.set_ylabel("energy (J)")
    ax_p.set_ylabel("linear momentum (kg m/s)")
    for ax, title in zip(axes, panel_titles(data), strict=True):
        if title:
            ax.set_title(title, fontsize=9)
    ax_l.set_ylabel("angular momentum (kg m²/s)")
    ax_l.set_xlabel("time (s)")
    for ax in (ax_e, ax_p, ax_l):
        ax.grid(True, alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=7, loc="best")
    output = os.fspath(output)
    # No dates in PDF/SVG metadata: the same inputs give the same bytes.
    suffix = os.path.splitext(output)[1].lower()
    metadata = {"Date": None} if suffix in (".pdf", ".svg") else None
    fig.savefig(output, metadata=metadata)
    return data
