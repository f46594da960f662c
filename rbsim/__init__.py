"""rbsim: a command-line scene runner for 2D rigid-body dynamics.

A YAML scene is stepped by rbsim's own impulse solver and written to an HDF5
trajectory (H5MD layout); `load_trajectory` reads one back as numpy arrays.
"""

import hashlib as _hashlib
import os as _os
from pathlib import Path as _Path

__version__ = "0.1.0"


# the modules that define numba kernels or the data they compile against
_KERNEL_MODULES = (
    "broadphase.py",
    "constants.py",
    "contacts.py",
    "integrator.py",
    "model.py",
    "narrowphase.py",
    "shock.py",
    "solver.py",
    "world.py",
)


def _kernel_cache_dir() -> str:
    """A numba cache folder keyed by a hash of rbsim's own source.

    numba invalidates a cached kernel only when the kernel's own file changes, not
    when a kernel it calls (in another module) does; keying the whole cache on the
    source of every kernel module makes a stale compiled step impossible.
    """
    digest = _hashlib.sha256()
    for name in _KERNEL_MODULES:
        path = _Path(__file__).parent / name
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    base = _os.environ.get("XDG_CACHE_HOME") or _os.path.join(_os.path.expanduser("~"), ".cache")
    return _os.path.join(base, "rbsim", "numba-" + digest.hexdigest()[:16])


if "NUMBA_CACHE_DIR" not in _os.environ:
    _os.environ["NUMBA_CACHE_DIR"] = _kernel_cache_dir()
    try:  # numba already imported by the caller: it reads its config then
        import sys as _sys

        if "numba" in _sys.modules:
            _sys.modules["numba"].core.config.CACHE_DIR = _os.environ["NUMBA_CACHE_DIR"]
    except AttributeError:
        pass


def load_trajectory(path):  # noqa: ANN001, ANN201 - re-exported, documented in trajectory
    """Read a trajectory file (rbsim or pymunk engine) into numpy arrays; see
    rbsim.trajectory.load_trajectory."""
    from .trajectory import load_trajectory as _load

    return _load(path)


__all__ = ["__version__", "load_trajectory"]
