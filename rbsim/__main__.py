"""`python -m rbsim` and the `rbsim` command (pyproject's entry point): the click group
of rbsim.cli, with a Ctrl-C that lands while Python still imports it ending as one during
a command does (exit 130 and a message, no traceback)."""

import sys

EXIT_INTERRUPTED = 130  # rbsim.cli's, not imported from there: that is what may be stopped


def entry() -> None:
    """Run the command line; a KeyboardInterrupt before click has started (the imports)
    exits 130 with a message, as the commands do."""
    try:
        from .cli import main

        main()
    except KeyboardInterrupt:
        sys.stderr.write("interrupted before the command started\n")
        sys.exit(EXIT_INTERRUPTED)


if __name__ == "__main__":  # not when a worker process imports it (spawn)
    entry()
