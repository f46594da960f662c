"""`python -m rbsim` and the `rbsim` command (pyproject's entry point): the click group
of rbsim.cli, with a Ctrl-C that lands while Python still imports it ending as one during
a command does (exit 130 and a message, no traceback)."""

import os
import sys

EXIT_INTERRUPTED = 130  # rbsim.cli's, not imported from there: that is what may be stopped


def _forget_the_interrupt() -> None:
    """Clear CPython's record of a KeyboardInterrupt that went through code run by
    PyRun_* (a compiled module's start-up code, say) even when it was then handled: at
    exit, CPython 3.11 would kill the process with SIGINT (exit -2) over our exit 130.
    Best effort: other versions keep that record elsewhere (nothing is done)."""
    try:
        import ctypes

        ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt").value = 0
    except (ImportError, ValueError, AttributeError, OSError):
        pass


def _quiet_from_here() -> None:
    """After a handled Ctrl-C, leave unprinted what the interpreter's exit still reports:
    objects the interrupt left half-made fail to close as the process ends (an h5py
    identifier, Ctrl-C landing 0.22 s into a run: "Can't decrement id ref count", two
    tracebacks after "interrupted"). Hooks without global names: they run while the
    modules are torn down."""
    sys.unraisablehook = lambda unraisable: None
    sys.excepthook = lambda *exc: None


# numpy's BLAS and OpenMP on one thread where the user has not chosen (set before numpy
# loads, which reads them once), as Dask sets them for its workers: rbsim's arrays are
# small, and OpenBLAS's idle threads spin on the other cores after each call, about 0.15 s
# of CPU in every command's start (`rbsim run` of a 5-body scene: 0.32 - 0.45 s of user
# time, 0.19 - 0.30 s on one thread)
ONE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_library_thread() -> None:
    """Set ONE_THREAD's variables to 1 in this process's environment where unset."""
    for name in ONE_THREAD:
        os.environ.setdefault(name, "1")


def entry() -> None:
    """Run the command line; a KeyboardInterrupt before click has started (the imports)
    exits 130 with a message, as the commands do."""
    one_library_thread()
    try:
        from . import ctrlc  # (inside: a Ctrl-C may land in any import)

        ctrlc.install()
        from .cli import main

        main()
    except KeyboardInterrupt:
        sys.stderr.write("interrupted before the command started\n")
        _forget_the_interrupt()
        _quiet_from_here()
        sys.exit(EXIT_INTERRUPTED)
    except SystemExit as done:
        if done.code == EXIT_INTERRUPTED:  # a Ctrl-C handled: exit 130, not SIGINT
            _forget_the_interrupt()
            _quiet_from_here()
        raise
    except Exception:
        ctrlc = sys.modules.get(f"{__package__}.ctrlc")
        if ctrlc is None or not ctrlc.arrived():
            raise
        sys.stderr.write("interrupted\n")  # what it broke (an import) raised something else
        _forget_the_interrupt()
        _quiet_from_here()
        sys.exit(EXIT_INTERRUPTED)


if __name__ == "__main__":  # not when a worker process imports it (spawn)
    entry()
