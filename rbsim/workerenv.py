"""Imported first by the fork server of a batch's local cluster (rbsim.forkserver):
sets, in the server and so in every worker forked from it, the environment variables
Dask sets before it spawns a worker ("distributed.nanny.pre-spawn-environ": one thread
for BLAS and OpenMP, a malloc trim threshold), where the user has not set them. Read
from Dask's configuration, with distributed's defaults loaded from its own file
without importing distributed (which imports numpy, which must see them first)."""

from __future__ import annotations

import importlib.util
import os
import signal

# The fork server starts with SIGINT blocked (rbsim.forkserver): from here on it and its
# workers ignore it (a Ctrl-C held back so far is dropped), and it is unblocked.
if signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, ()):
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})

import dask  # noqa: E402 - after the signal's handling, which should come first
import yaml  # noqa: E402


def _pre_spawn_environ() -> dict[str, str]:
    """Dask's pre-spawn environment, as strings."""
    spec = importlib.util.find_spec("distributed")
    if spec is not None and spec.submodule_search_locations:
        path = os.path.join(spec.submodule_search_locations[0], "distributed.yaml")
        with open(path, encoding="utf-8") as f:
            dask.config.update_defaults(yaml.safe_load(f))
    environ = dask.config.get("distributed.nanny.pre-spawn-environ", default={}) or {}
    return {str(k): str(v) for k, v in environ.items()}


for _key, _value in _pre_spawn_environ().items():
    os.environ.setdefault(_key, _value)
