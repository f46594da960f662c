"""Shared helpers: scenes from inline YAML, run to a trajectory in a temp folder."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from rbsim import cli
from rbsim.io.trajectory import Trajectory, load_trajectory
from rbsim.scene import Scene, load_scene_text


def scene_from(text: str, overrides: tuple[str, ...] = ()) -> Scene:
    """A resolved scene from inline YAML (dedented)."""
    return load_scene_text(textwrap.dedent(text), "inline.yaml", overrides)


@pytest.fixture
def run_text(tmp_path: Path):
    """Run an inline scene with rbsim and return its loaded trajectory."""
    from rbsim.run import run_scene

    counter = iter(range(10**6))

    def _run(text: str, overrides: tuple[str, ...] = ()) -> Trajectory:
        scene = scene_from(text, overrides)
        out = tmp_path / f"run{next(counter)}.h5"
        run_scene(scene, out)
        return load_trajectory(out)

    return _run


def rbsim(*args: str | Path) -> tuple[int, str, str]:
    """Run the CLI in this process: (exit code, stdout, stderr). An exception that the
    CLI did not turn into an exit code (it would print a traceback) fails the test."""
    try:
        runner = CliRunner(mix_stderr=False)  # click < 8.2 mixes the streams otherwise
    except TypeError:
        runner = CliRunner()
    result = runner.invoke(cli.main, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.stdout, result.stderr
