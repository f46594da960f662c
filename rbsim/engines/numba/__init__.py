"""The numba engine ("rbsim-numba") that the compiled engine was ported from, kept
until the port is complete so that the two can be held against each other (tests/port).

world.py is the step; broadphase, narrowphase, contacts, solver, shock and integrator
are its stages. Importing this package points numba's cache at a folder keyed by the
kernels' source (below); nothing else of rbsim imports numba.
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

# the files that define numba kernels or the data they compile against
_HERE = Path(__file__).resolve().parent
_ROOT = _HERE.parent.parent
KERNEL_SOURCES = (
    *(_HERE / f"{name}.py" for name in (
        "broadphase", "contacts", "integrator", "narrowphase", "shock", "solver", "world",
    )),
    _ROOT / "constants.py",
    _ROOT / "scene" / "types.py",
    _ROOT / "scene" / "compile.py",
)  # fmt: skip


def kernel_cache_dir() -> str:
    """A numba cache folder keyed by a hash of the kernels' source.

    numba invalidates a cached kernel only when the kernel's own file changes, not
    when a kernel it calls (in another module) does; keying the whole cache on the
    source of every kernel module makes a stale compiled step impossible.
    """
    digest = hashlib.sha256()
    for path in KERNEL_SOURCES:
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "rbsim", "numba-" + digest.hexdigest()[:16])


if "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = kernel_cache_dir()
    if "numba" in sys.modules:  # numba already imported by the caller: it read its config
        try:
            sys.modules["numba"].core.config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]
        except AttributeError:
            pass
