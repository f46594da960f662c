"""rbsim: a command-line scene runner for 2D rigid-body dynamics.

A YAML scene is stepped by rbsim's own impulse solver and written to an HDF5
trajectory (H5MD layout); `run(scene)` runs one and returns its trajectory in memory,
`load_scene` reads a scene, `load_trajectory` reads a
trajectory back as numpy arrays, and `World.from_scene(scene)` is a scene ready to step
in the compiled engine (`advance(n)`, the state as numpy views). Importing rbsim has no
side effects and imports nothing heavy: each is loaded on first use.

The package, top down (imports point down): cli -> batch -> tools -> run, view,
engines -> io, core -> scene.
"""

from __future__ import annotations

__version__ = "0.1.0"


def load_scene(path, overrides=()):  # noqa: ANN001, ANN201 - re-exported, documented in scene
    """Read, check and resolve a scene file; see rbsim.scene.load_scene."""
    from .scene import load_scene as _load

    return _load(path, overrides)


def load_trajectory(path):  # noqa: ANN001, ANN201 - re-exported, documented in io.trajectory
    """Read a trajectory file (rbsim or pymunk engine) into numpy arrays; see
    rbsim.io.trajectory.load_trajectory."""
    from .io.trajectory import load_trajectory as _load

    return _load(path)


def run(scene, out=None, overrides=()):  # noqa: ANN001, ANN201 - documented in rbsim.run
    """Run a scene (a path, YAML text or a dict) and return its trajectory in memory;
    see rbsim.run.run. (Once the module rbsim.run is imported, `rbsim.run` is that
    module, which is callable and does the same.)"""
    from .run import run as _run

    return _run(scene, out, overrides)


def __getattr__(name: str):  # noqa: ANN202 - module attributes loaded on first use
    if name == "World":  # the compiled engine's world (rbsim.core.CoreWorld)
        from .core import CoreWorld

        return CoreWorld
    raise AttributeError(f"module 'rbsim' has no attribute {name!r}")


__all__ = ["World", "__version__", "load_scene", "load_trajectory", "run"]
