"""Ctrl-C before a command has its own handling of it (standard library only).

`rbsim`'s entry point installs `handler`: Python's own handling of SIGINT (raise
KeyboardInterrupt where the program is), which also counts each Ctrl-C. The count tells
what became of one that landed somewhere that does not pass a KeyboardInterrupt on:
inside a compiled module's import it comes out as that module's ImportError (h5py's:
"Failed to import 'zlib.decompress'"), and inside a weakref callback or a __del__ (one
of importlib's module locks, while Dask is imported) Python prints "Exception ignored"
and goes on. Any Ctrl-C ends the program, so a count above zero where the program goes
on means one was lost: `raise_if_arrived` raises it again where a command is about to
start its long work. The "Exception ignored" report of one lost so (a traceback) is not
printed.
"""

from __future__ import annotations

import signal
import sys
from types import FrameType
from typing import Any

_arrived = 0  # Ctrl-Cs handled by `handler`
_report = sys.unraisablehook  # how an exception that cannot be raised is reported


def handler(signum: int, frame: FrameType | None) -> None:  # noqa: ARG001 - a signal handler
    """Raise KeyboardInterrupt, as Python's own handler does, and count the Ctrl-C."""
    global _arrived
    _arrived += 1
    raise KeyboardInterrupt


def _unraisable(unraisable: Any) -> None:
    """sys.unraisablehook: silent for a KeyboardInterrupt of `handler`'s (it is raised
    again: raise_if_arrived), the report before for anything else."""
    if not (_arrived and isinstance(unraisable.exc_value, KeyboardInterrupt)):
        _report(unraisable)


def install() -> None:
    """Handle SIGINT with `handler` where Python's own handler is in place (not where it
    is ignored, as in a background job; only from the main thread)."""
    global _report
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, handler)
        _report = sys.unraisablehook
        sys.unraisablehook = _unraisable


def arrived() -> bool:
    """Whether a Ctrl-C has reached `handler`."""
    return _arrived > 0


def raise_if_arrived() -> None:
    """Raise KeyboardInterrupt if a Ctrl-C reached `handler`: the program is still
    running, so the KeyboardInterrupt it raised was lost where it landed."""
    if _arrived:
        raise KeyboardInterrupt
