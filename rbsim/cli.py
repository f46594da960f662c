"""The `rbsim` command line: click commands only, no physics.

Exit codes (DESIGN.md): 0 ok; 1 runtime failure; 2 usage error; 3 invalid scene;
4 compare outside tolerance; 130 interrupted.
"""

from __future__ import annotations

import json
import signal
import sys
import time
from pathlib import Path

import click

from . import __version__

EXIT_RUNTIME = 1
EXIT_SCENE = 3
EXIT_INTERRUPTED = 130


def _load(path: str, overrides: tuple[str, ...] = ()):
    """Load a scene or exit 3 with the validator's messages."""
    from .scene import SceneError, load_scene

    try:
        return load_scene(path, overrides)
    except SceneError as err:
        click.echo(str(err), err=True)
        sys.exit(EXIT_SCENE)


def _raise_interrupt(signum, frame):  # noqa: ARG001 - signal handler signature
    raise KeyboardInterrupt


class _Progress:
    """A progress line on stderr, shown only on a terminal and after the first second."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self.t0 = time.perf_counter()
        self.shown = False

    def __call__(self, step: int, total: int) -> None:
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.t0
        if elapsed < 1.0:
            return
        width = 30
        filled = int(width * step / max(total, 1))
        rate = step / elapsed
        eta = (total - step) / rate if rate > 0 else 0.0
        sys.stderr.write(
            f"\r[{'#' * filled}{'.' * (width - filled)}] {step}/{total} steps "
            f"{rate:,.0f}/s eta {eta:.0f} s "
        )
        sys.stderr.flush()
        self.shown = True

    def finish(self) -> None:
        if self.shown:
            sys.stderr.write("\n")
            sys.stderr.flush()


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="rbsim")
def main() -> None:
    """rbsim: run 2D rigid-body scenes (YAML) into HDF5 trajectories."""


@main.command()
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--output",
    "output",
    type=click.Path(dir_okay=False),
    help="Trajectory file to write [default: out/<scene name>.h5].",
)
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY.PATH=VALUE",
    help="Override a scene value, e.g. --set world.dt=0.005 (repeatable).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
def run(scene: str, output: str | None, overrides: tuple[str, ...], quiet: bool) -> None:
    """Step SCENE with rbsim's solver and write its trajectory."""
    from .model import ModelError
    from .run import RunFailed, run_scene

    sc = _load(scene, overrides)
    out = Path(output) if output else Path("out") / f"{sc.name}.h5"
    out.parent.mkdir(parents=True, exist_ok=True)
    signal.signal(signal.SIGTERM, _raise_interrupt)
    progress = _Progress(not quiet)
    try:
        summary = run_scene(sc, out, progress=progress)
    except ModelError as err:
        progress.finish()
        click.echo(f"{scene}: {err}", err=True)
        sys.exit(EXIT_SCENE)
    except RunFailed as err:
        progress.finish()
        click.echo(f"error: {err}", err=True)
        sys.exit(EXIT_RUNTIME)
    except KeyboardInterrupt:
        progress.finish()
        click.echo(f"interrupted: frames so far kept in {out}", err=True)
        sys.exit(EXIT_INTERRUPTED)
    except OSError as err:
        progress.finish()
        click.echo(f"error: cannot write {out}: {err}", err=True)
        sys.exit(EXIT_RUNTIME)
    progress.finish()
    if not quiet:
        click.echo(summary.line())


@main.command()
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option("--resolved", is_flag=True, help="Print the fully resolved scene (YAML).")
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="As for run.")
def validate(scene: str, resolved: bool, overrides: tuple[str, ...]) -> None:
    """Check SCENE against the version-1 format; exit 3 with every error found."""
    import yaml

    from .scene import scene_to_dict

    sc = _load(scene, overrides)
    if resolved:
        click.echo(yaml.safe_dump(scene_to_dict(sc), sort_keys=False), nl=False)
    else:
        n = len(sc.bodies)
        click.echo(f"{scene}: ok ({n} bodies, {sc.world.steps} steps of {sc.world.dt:g} s)")


@main.command()
@click.argument("trajectory", type=click.Path(exists=True, dir_okay=False))
def info(trajectory: str) -> None:
    """Summarise a trajectory file written by rbsim (either engine)."""
    from .trajectory import summarize

    try:
        click.echo(summarize(trajectory))
    except (OSError, KeyError, ValueError) as err:
        click.echo(f"{trajectory}: not a readable rbsim trajectory ({err})", err=True)
        sys.exit(EXIT_RUNTIME)


@main.command()
def schema() -> None:
    """Print the JSON Schema of the scene format (for editors)."""
    from .schema import json_schema

    click.echo(json.dumps(json_schema(), indent=2))


if __name__ == "__main__":
    main()
