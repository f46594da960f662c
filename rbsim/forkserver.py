"""The fork server that a batch's local Dask cluster forks its workers from.

A worker forked from a server that has already imported what the runs need starts in
a fraction of the time and CPU of a spawned one, and leaves without Python's
finalization. The server imports WORKER_MODULES once, when it starts, and that takes
about a second; so `rbsim batch` starts it first of all (this module imports only the
standard library), and the server imports on the other core while the batch imports
Dask and checks its runs. Its first import, rbsim.workerenv, sets the variables Dask
sets before it spawns a worker (one thread for BLAS and OpenMP), before numpy loads.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

# Modules a worker of a local cluster needs for its runs: imported once, when the
# workers start (by the fork server they are forked from, or by batch.dask_setup).
WORKER_MODULES = (
    "numpy",
    "h5py",
    "distributed",
    "rbsim.batch",
    "rbsim.run",
    "rbsim.io.trajectory",
    "rbsim.tools.measure",
)

# The hash seed of the server (and so of every worker forked from it) when the user set
# none: Dask gives its spawned workers one fixed seed, and a worker's seed can only be
# set when its interpreter starts.
HASH_SEED = "6640"


def start_fork_server() -> bool:
    """Start the fork server (once per process; later calls return at once), from the
    main thread with SIGINT blocked: the server starts with it blocked, and its first
    import (rbsim.workerenv) ignores it and unblocks it, so Ctrl-C never reaches the
    server or a worker forked from it, even while it starts. This process only holds a
    Ctrl-C back while it starts the server (ignoring it here, as the server must, would
    lose it: the batch would go on). False where there is no fork server (Windows) or
    this is not the main thread: the workers are then spawned."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return False
    if threading.current_thread() is not threading.main_thread():
        return False
    from multiprocessing import forkserver

    multiprocessing.get_context("forkserver").set_forkserver_preload(
        ["rbsim.workerenv", *WORKER_MODULES]
    )
    seed = os.environ.get("PYTHONHASHSEED")
    if seed in (None, "0"):
        os.environ["PYTHONHASHSEED"] = HASH_SEED
    with holding_sigint():
        try:
            forkserver.ensure_running()
        finally:
            if seed is None:
                del os.environ["PYTHONHASHSEED"]
            else:
                os.environ["PYTHONHASHSEED"] = seed
    return True


@contextmanager
def holding_sigint() -> Iterator[None]:
    """Inside the block, a Ctrl-C (SIGINT) is held back: noted, and handled on leaving as
    it would have been then (by the handler in place before: a KeyboardInterrupt, raised
    here). SIGINT is blocked in this thread (the main thread) meanwhile, so that the
    processes it starts inherit it blocked; one that reaches another thread is noted
    alike."""
    previous = signal.getsignal(signal.SIGINT)
    arrived: list[int] = []
    if previous is not None:  # None: a handler not set from Python, left alone
        signal.signal(signal.SIGINT, lambda signum, frame: arrived.append(signum))  # noqa: ARG005
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)  # one blocked so far is noted now
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
            if arrived and callable(previous):
                previous(signal.SIGINT, None)  # in this thread (a signal sent again may not be)
            elif arrived and previous == signal.SIG_DFL:
                os.kill(os.getpid(), signal.SIGINT)


@contextmanager
def ignoring_sigint() -> Iterator[None]:
    """SIGINT ignored inside the block, for the processes started there to inherit (a
    Ctrl-C that arrives meanwhile is lost)."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
