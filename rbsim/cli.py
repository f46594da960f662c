"""The `rbsim` command line: click commands only, no physics.

Exit codes (cli.md): 0 ok; 1 runtime failure; 2 usage error; 3 invalid scene;
4 compare outside tolerance; 130 interrupted.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import click

from . import __version__

if TYPE_CHECKING:
    from .run import RunSummary
    from .scene import Scene

EXIT_RUNTIME = 1
EXIT_SCENE = 3
EXIT_COMPARE = 4
EXIT_INTERRUPTED = 130


class _FiniteFloat(click.FloatRange):
    """click's FloatRange that also refuses nan and inf (which pass its comparisons, or
    lie within an open range): a usage error naming the option. -0 reads as 0."""

    def convert(self, value, param, ctx):  # noqa: ANN001, ANN201 - click's signature
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return number + 0.0


_POSITIVE = _FiniteFloat(min=0, min_open=True)  # a length of time, s
_NON_NEGATIVE = _FiniteFloat(min=0)  # a tolerance
_FINITE = _FiniteFloat()  # a time or a coordinate

# A scene file: one that cannot be read (or is missing) is load_scene's to report, as an
# invalid scene at its line 1 (exit 3), not click's "is not readable" (exit 2).
_SCENE = click.Path(dir_okay=False, readable=False)


def _not_empty(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """A path option's value, refused when empty (-o ""): Path("") is the current folder,
    which a run would report as "cannot write .: not a regular file" (exit 1)."""
    if value == "":
        raise click.BadParameter("the path is empty", ctx=ctx, param=param)
    return value


# Problems listed at most, then "... and N more problems" (a 20,000-body scene made 3D
# by --set has 60,000): the cap of rbsim batch's list (batch.MAX_LISTED).
MAX_LISTED = 20


def _listed(lines: list[str]) -> str:
    """The first MAX_LISTED of `lines` (one problem each) and, when there are more, a
    last line saying how many."""
    shown = lines[:MAX_LISTED]
    if len(lines) > MAX_LISTED:
        more = len(lines) - MAX_LISTED
        shown.append(f"... and {more:,} more problem{'s' if more > 1 else ''}")
    return "\n".join(shown)


def _load(path: str, overrides: tuple[str, ...] = ()):
    """Load a scene or exit 3 with the validator's messages (the first MAX_LISTED)."""
    from .scene import SceneError, load_scene

    try:
        scene = load_scene(path, overrides)
    except SceneError as err:
        _fail(EXIT_SCENE, _listed([str(issue) for issue in err.errors]))
    for note in scene.notes:
        click.echo(str(note), err=True)
    return scene


def _load_reference(
    path: str, overrides: tuple[str, ...], extra: dict[str, tuple[str, ...]], base: Scene
) -> Scene:
    """Load the reference engine's scene: `overrides` (--set), then each option's lines of
    `extra` ({"--pymunk-set": lines, ...}); exit 3 with the validator's messages, a
    problem of one of those lines naming its option, not --set (the lines go through
    load_scene as --set lines). Only the notes that `base` (the scene of `overrides`
    alone, whose notes _load printed) does not have are printed."""
    from .scene import SceneError, load_scene

    option_of = {}  # the key of a line, as a SceneIssue names it -> its option (the last)
    for option, lines in extra.items():
        for line in lines:
            key = line.partition("=")[0].strip()
            option_of[key or line] = option

    def relabel(issue) -> str:  # noqa: ANN001 - a SceneIssue
        text = str(issue)
        option = option_of.get(issue.override) if issue.override is not None else None
        if option is None:
            return text
        return text.replace(f"{issue.file}: --set ", f"{issue.file}: {option} ", 1)

    try:
        scene = load_scene(path, overrides + tuple(line for v in extra.values() for line in v))
    except SceneError as err:
        _fail(EXIT_SCENE, _listed([relabel(issue) for issue in err.errors]))
    seen = {str(note) for note in base.notes}
    for note in scene.notes:
        if str(note) not in seen:
            click.echo(relabel(note), err=True)
    return scene


def _raise_interrupt(signum, frame):  # noqa: ARG001 - signal handler signature
    raise KeyboardInterrupt


class _Progress:
    """A progress line on stderr, shown only when stderr is a terminal and only once the
    run has taken a second (short runs print nothing); redrawn at most every 0.1 s."""

    DELAY = 1.0  # s before the line first appears
    INTERVAL = 0.1  # s between redraws

    def __init__(self, enabled: bool, unit: str = "steps") -> None:
        self.unit = unit
        try:
            self.enabled = enabled and sys.stderr is not None and sys.stderr.isatty()
        except (AttributeError, ValueError):  # stderr replaced or closed
            self.enabled = False
        self.t0 = time.perf_counter()
        self.last = 0.0
        self.shown = False

    def __call__(self, step: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        elapsed = now - self.t0
        if elapsed < self.DELAY or (now - self.last < self.INTERVAL and step < total):
            return
        self.last = now
        width = 30
        filled = int(width * step / max(total, 1))
        rate = step / elapsed
        eta = (total - step) / rate if rate > 0 else 0.0
        try:
            sys.stderr.write(
                f"\r[{'#' * filled}{'.' * (width - filled)}] {step}/{total} {self.unit} "
                f"{rate:,.0f}/s eta {eta:.0f} s "
            )
            sys.stderr.flush()
        except (OSError, ValueError):  # the terminal went away: stop drawing
            self.enabled = False
            return
        self.shown = True

    def finish(self) -> None:
        """End the progress line (if one was drawn) so that messages start on a new line."""
        if self.shown:
            self.shown = False
            try:
                sys.stderr.write("\n")
                sys.stderr.flush()
            except (OSError, ValueError):
                pass


def _fail(code: int, message: str, progress: _Progress | None = None) -> NoReturn:
    """End the progress line, print `message` on stderr and exit with `code`."""
    if progress is not None:
        progress.finish()
    click.echo(message, err=True)
    sys.exit(code)


def _reason(err: OSError) -> str:
    """The system's short reason for an OSError ("Permission denied"), else its text
    (run.system_reason, imported only on this error path: the front starts without it)."""
    from .run import system_reason

    return system_reason(err)


class _BatchProgress(_Progress):
    """The batch's one progress line: runs finished of the total, failed, ETA."""

    def __init__(self, enabled: bool) -> None:
        super().__init__(enabled, unit="runs")
        self.started: tuple[float, int] | None = None  # (time, runs finished) at the first call

    def runs(self, done: int, failed: int, total: int) -> None:
        """Redraw with `done` runs finished (`failed` of them failed) of `total`."""
        now = time.perf_counter()
        if self.started is None:  # runs skipped as complete do not count towards the rate
            self.started = (now, done)
        if not self.enabled:
            return
        elapsed = now - self.t0
        if elapsed < self.DELAY or (now - self.last < self.INTERVAL and done < total):
            return
        self.last = now
        t_start, done_start = self.started
        ran = done - done_start
        eta = (total - done) * (now - t_start) / ran if ran > 0 else None
        width = 30
        filled = int(width * done / max(total, 1))
        eta_text = f"eta {eta:.0f} s" if eta is not None else "eta -"
        try:
            sys.stderr.write(
                f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} runs, "
                f"{failed} failed, {eta_text} "
            )
            sys.stderr.flush()
        except (OSError, ValueError):
            self.enabled = False
            return
        self.shown = True


def _cluster_options(function):  # noqa: ANN001, ANN202 - a click decorator
    return click.option(
        "--scheduler",
        metavar="ADDRESS",
        help="Run on the Dask cluster of this scheduler (tcp://host:8786).",
    )(
        click.option(
            "--workers",
            type=click.IntRange(min=1),
            help="Worker processes of a local Dask cluster [default: every core].",
        )(function)
    )


def _interrupted(message: str = "interrupted") -> NoReturn:
    """Exit 130 with `message` for a Ctrl-C (or SIGTERM) that no command handled; a
    second one meanwhile (in the main thread) is ignored, so that the exit stays clean."""
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    try:
        _fail(EXIT_INTERRUPTED, message)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


class _Commands(click.Group):
    """click's group, whose Ctrl-C ends with exit 130 and a message at any moment: click
    itself turns a KeyboardInterrupt that no command caught (one while the arguments are
    parsed, or before a command has installed its own handling) into "Aborted!" and
    exit 1."""

    def make_context(
        self,
        info_name: str | None,
        args: list[str],
        parent: click.Context | None = None,
        **extra: object,
    ) -> click.Context:
        """click's, with a Ctrl-C while parsing the arguments exiting 130."""
        try:
            return super().make_context(info_name, args, parent, **extra)  # type: ignore[arg-type]
        except KeyboardInterrupt:
            _interrupted()

    def invoke(self, ctx: click.Context) -> object:
        """click's, with a Ctrl-C that the command did not handle exiting 130."""
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            _interrupted()


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="rbsim")
def main() -> None:
    """rbsim: run 2D and 3D rigid-body scenes (YAML) into HDF5 trajectories."""


@main.command()
@click.argument("scene", type=_SCENE, required=False)
@click.option(
    "-o",
    "--output",
    "output",
    type=click.Path(dir_okay=False),
    callback=_not_empty,
    help="Trajectory file to write [default: out/<scene name>.h5].",
)
@click.option(
    "--resume",
    "resume",
    type=click.Path(dir_okay=False),
    callback=_not_empty,
    metavar="OUT.h5",
    help="Continue the interrupted or killed run of this trajectory (no SCENE).",
)
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY.PATH=VALUE",
    help="Override a scene value, e.g. --set world.dt=0.005 (repeatable).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@click.option(
    "--force",
    is_flag=True,
    help="Replace OUTPUT even when it is not an rbsim trajectory (or is SCENE itself).",
)
def run(
    scene: str | None,
    output: str | None,
    resume: str | None,
    overrides: tuple[str, ...],
    quiet: bool,
    force: bool,
) -> None:
    """Step SCENE with rbsim's solver and write its trajectory."""
    started = _process_start()
    if resume is not None and (scene is not None or output is not None or overrides):
        raise click.UsageError("--resume OUT.h5 takes no SCENE, -o or --set: the file has them")
    if resume is None and scene is None:
        raise click.UsageError("missing argument SCENE (or --resume OUT.h5)")
    if output is not None:
        _check_output(scene, output, force)
    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread:  # SIGTERM ends a run like Ctrl-C (only the main thread may set it)
        previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    progress = _Progress(not quiet)
    try:
        if resume is not None:
            summary = _resume(resume, progress, started)
        else:
            summary = _run(scene, output, overrides, progress, started=started)
    except KeyboardInterrupt as err:
        # run.RunInterrupted once the file exists: it says how many frames it kept
        if getattr(err, "frames", None) is not None:
            message = str(err)
        else:
            message = "interrupted before the trajectory file was created"
        _fail(EXIT_INTERRUPTED, message, progress)
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)
    progress.finish()
    if not quiet:
        click.echo(summary.line())


def _check_output(scene: str, output: str, force: bool) -> None:
    """Refuse an existing OUTPUT that the run must not replace: exit 1 for one that is no
    regular file (/dev/null: HDF5 needs a file it can seek in), a usage error (2) for the
    scene file itself or a file that is not an rbsim trajectory, unless `force`."""
    out = Path(output)
    if not out.exists():
        return
    if not out.is_file():  # a directory is click's usage error already
        _fail(EXIT_RUNTIME, f"error: cannot write {out}: not a regular file")
    if force:
        return
    try:
        same = Path(scene).exists() and os.path.samefile(scene, out)
    except OSError:
        same = False
    if same:
        raise click.BadParameter(
            f"{output} is the scene file itself; give another output file (or --force)",
            param_hint="'-o' / '--output'",
        )
    if out.stat().st_size and not _is_trajectory(out):
        raise click.BadParameter(
            f"{output} exists and is not an rbsim trajectory; not replacing it without --force",
            param_hint="'-o' / '--output'",
        )


def _is_trajectory(path: Path) -> bool:
    """Whether `path` is an HDF5 file written by rbsim (its /h5md/creator says so)."""
    import h5py

    try:
        if not h5py.is_hdf5(path):
            return False
        with h5py.File(path, "r", locking=False) as f:
            creator = f.get("h5md/creator")
            return creator is not None and creator.attrs.get("name") == "rbsim"
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _run(
    scene: str,
    output: str | None,
    overrides: tuple[str, ...],
    progress: _Progress,
    engine: str = "rbsim",
    started: float | None = None,
) -> RunSummary:
    """Load and run SCENE; every expected failure becomes a message and an exit code."""
    from .run import RunFailed, WriteFailed, file_stem, run_scene
    from .scene.compile import ModelError

    sc = _load(scene, overrides)
    out = Path(output) if output else Path("out") / f"{file_stem(sc.name)}.h5"
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        return run_scene(
            sc,
            out,
            progress=progress,
            signals=(signal.SIGINT, signal.SIGTERM),
            engine=engine,
            overrides=overrides,
            started=started,
        )
    except ModelError as err:
        _fail(EXIT_SCENE, f"{scene}: {err}", progress)
    except RunFailed as err:
        _fail(EXIT_RUNTIME, f"error: {err}", progress)
    except MemoryError:
        message = f"error: {scene}: out of memory (the file keeps the frames before it: {out})"
        _fail(EXIT_RUNTIME, message, progress)
    except FileExistsError:  # from mkdir: a file where a folder should be
        _fail(EXIT_RUNTIME, f"error: cannot write {out}: {out.parent} is not a folder", progress)
    except WriteFailed as err:  # says what the file keeps
        _fail(EXIT_RUNTIME, f"error: {err}", progress)
    except OSError as err:
        _fail(EXIT_RUNTIME, f"error: cannot write {out}: {_reason(err)}", progress)


def _resume(path: str, progress: _Progress, started: float | None) -> RunSummary:
    """Resume the run of trajectory `path`; failures become messages and exit codes."""
    from .run import ResumeError, RunFailed, WriteFailed, resume_run
    from .scene import SceneError

    try:
        return resume_run(
            path, progress=progress, signals=(signal.SIGINT, signal.SIGTERM), started=started
        )
    except ResumeError as err:
        _fail(EXIT_RUNTIME, f"error: cannot resume: {err}", progress)
    except SceneError as err:
        problems = _listed([str(issue) for issue in err.errors])
        _fail(EXIT_SCENE, f"{path}: the scene it records is no longer valid:\n{problems}", progress)
    except RunFailed as err:
        _fail(EXIT_RUNTIME, f"error: {err}", progress)
    except WriteFailed as err:
        _fail(EXIT_RUNTIME, f"error: {err}", progress)
    except OSError as err:
        _fail(EXIT_RUNTIME, f"error: cannot write {path}: {_reason(err)}", progress)


def _process_start() -> float | None:
    from .run import process_start

    return process_start()


@main.command()
@click.argument("scene", type=_SCENE)
@click.option("--resolved", is_flag=True, help="Print the fully resolved scene (YAML).")
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="As for run.")
def validate(scene: str, resolved: bool, overrides: tuple[str, ...]) -> None:
    """Check SCENE against the version-1 format; exit 3 with every error found."""
    import yaml

    from .scene import scene_to_dict
    from .scene.schema import counted

    sc = _load(scene, overrides)
    if resolved:
        click.echo(yaml.safe_dump(scene_to_dict(sc), sort_keys=False), nl=False)
    else:
        bodies = counted(len(sc.bodies), "body", "bodies")
        steps = counted(sc.world.steps, "step")
        click.echo(f"{scene}: ok ({bodies}, {steps} of {sc.world.dt:g} s)")


@main.command()
@click.argument("trajectory", type=click.Path(exists=True, dir_okay=False))
def info(trajectory: str) -> None:
    """Summarise a trajectory file written by rbsim (either engine)."""
    from .io.trajectory import READ_ERRORS, summarize, unreadable

    try:
        text = summarize(trajectory)
    except PermissionError as err:
        _fail(EXIT_RUNTIME, f"error: {trajectory}: cannot read: {_reason(err)}")
    except READ_ERRORS as err:  # worded as by render and plot
        _fail(EXIT_RUNTIME, f"error: {unreadable(trajectory, err)}")
    click.echo(text)


@main.command()
@click.argument("scene", type=_SCENE)
@click.option(
    "-o",
    "--output",
    "out_dir",
    type=click.Path(file_okay=False),
    callback=_not_empty,
    default="out/compare",
    show_default=True,
    help="Folder for <name>.rbsim.h5 and <name>.pymunk.h5 (<name>.mujoco.h5 in 3D).",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="As for run.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON dict instead of the table.")
@click.option("--position", type=_NON_NEGATIVE, help="Position tolerance, m.")
@click.option("--angle", type=_NON_NEGATIVE, help="Angle tolerance, rad.")
@click.option("--velocity", type=_NON_NEGATIVE, help="Velocity tolerance, m/s.")
@click.option(
    "--iterations",
    type=click.IntRange(min=1),
    help="pymunk solver iterations per pymunk step [default: compare.iterations, else 10].",
)
@click.option(
    "--statistics",
    "with_statistics",
    is_flag=True,
    help="Also compare statistics of the runs (for chaotic scenes).",
)
@click.option(
    "--pymunk-set",
    "pymunk_overrides",
    multiple=True,
    metavar="KEY.PATH=VALUE",
    help="Override a scene value for the reference engine only (pymunk in 2D, MuJoCo in "
    "3D), after --set.",
)
@click.option(
    "--reference-set",
    "reference_overrides",
    multiple=True,
    metavar="KEY.PATH=VALUE",
    help="The same as --pymunk-set (applied after it).",
)
def compare(
    scene: str,
    out_dir: str,
    overrides: tuple[str, ...],
    as_json: bool,
    position: float | None,
    angle: float | None,
    velocity: float | None,
    iterations: int | None,
    with_statistics: bool,
    pymunk_overrides: tuple[str, ...],
    reference_overrides: tuple[str, ...],
) -> None:
    """Run SCENE in rbsim and in a reference engine (pymunk in 2D, MuJoCo in 3D) and
    report their differences (exit 4 when a difference exceeds its tolerance)."""
    from .engines import EngineUnavailable, UnsupportedScene
    from .run import RunFailed
    from .scene.compile import ModelError
    from .tools.compare import compare_scene, reference_engine

    sc = _load(scene, overrides)
    extra = {"--pymunk-set": pymunk_overrides, "--reference-set": reference_overrides}
    pm_sc = _load_reference(scene, overrides, extra, sc) if any(extra.values()) else None
    out = Path(out_dir)
    try:
        result = compare_scene(
            sc,
            out,
            position=position,
            angle=angle,
            velocity=velocity,
            iterations=iterations,
            with_statistics=with_statistics,
            pymunk_scene=pm_sc,
        )
    except UnsupportedScene as err:
        _fail(EXIT_SCENE, f"{scene}: {reference_engine(sc)} cannot express this scene: {err}")
    except EngineUnavailable as err:
        _fail(EXIT_RUNTIME, f"{scene}: {err}")
    except ModelError as err:
        _fail(EXIT_SCENE, f"{scene}: {err}")
    except RunFailed as err:
        _fail(EXIT_RUNTIME, f"error: {err}")
    except KeyboardInterrupt:
        _fail(EXIT_INTERRUPTED, "interrupted")
    except FileExistsError:
        _fail(EXIT_RUNTIME, f"error: cannot write to {out}: it is not a folder")
    except OSError as err:
        _fail(EXIT_RUNTIME, f"error: cannot write to {out}: {_reason(err)}")
    if as_json:
        click.echo(json.dumps(result.to_dict(), indent=2))
    else:
        click.echo(result.table())
    if not result.ok:
        lines = [f"{scene}: outside tolerance: {v}" for v in result.violations]
        _fail(EXIT_COMPARE, "\n".join(lines))


@main.command()
@click.argument("trajectory", type=click.Path(exists=True, dir_okay=False))
@click.option(
    "-o",
    "--output",
    "output",
    type=click.Path(dir_okay=False),
    callback=_not_empty,
    help="movie.gif or page.html [default: TRAJECTORY with .gif].",
)
@click.option(
    "--fps",
    type=_POSITIVE,
    default=30.0,
    show_default=True,
    help="Frames per second of simulated time (GIF: at most 50).",
)
@click.option(
    "--view",
    nargs=4,
    type=_FINITE,
    metavar="X0 Y0 X1 Y1",
    help="2D only: world rectangle to show, m [default: fitted to the moving bodies].",
)
@click.option(
    "--size",
    nargs=2,
    type=click.IntRange(min=16, max=4096),
    default=(640, 480),
    show_default=True,
    metavar="W H",
    help="GIF size in pixels.",
)
@click.option(
    "--overlay",
    type=click.Path(exists=True, dir_okay=False),
    help="A second trajectory drawn over the first in its own colour.",
)
@click.option("--start", type=_FINITE, metavar="SECONDS", help="Show from this time on, s.")
@click.option("--end", type=_FINITE, metavar="SECONDS", help="Show up to this time, s.")
@click.option(
    "--contacts/--no-contacts",
    default=True,
    show_default=True,
    help="Draw the contact points the run recorded (output.contacts: points); in a page, "
    "shown until toggled off.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
def render(
    trajectory: str,
    output: str | None,
    fps: float,
    view: tuple[float, float, float, float] | None,
    size: tuple[int, int],
    overlay: str | None,
    start: float | None,
    end: float | None,
    contacts: bool,
    quiet: bool,
) -> None:
    """Draw TRAJECTORY into an animated GIF or a self-contained HTML player."""
    from .scene.schema import counted
    from .view.player import HTML_MAX_FPS
    from .view.render import GIF_MAX_FPS, RenderError, View, overlay_mismatch, render_gif

    out = Path(output) if output else Path(trajectory).with_suffix(".gif")
    kind = out.suffix.lower()
    if kind not in (".gif", ".html", ".htm"):
        raise click.BadParameter(
            f"{out}: the output must end in .gif or .html", param_hint="'-o' / '--output'"
        )
    if kind == ".gif" and fps > GIF_MAX_FPS:
        raise click.BadParameter(
            f"{fps:g}: a GIF plays at most {GIF_MAX_FPS:g} frames per second "
            "(viewers slow shorter delays down)",
            param_hint="'--fps'",
        )
    if kind != ".gif" and fps > HTML_MAX_FPS:
        raise click.BadParameter(
            f"{fps:g}: a page plays at most {HTML_MAX_FPS:g} frames per second",
            param_hint="'--fps'",
        )
    if view and not (view[0] < view[2] and view[1] < view[3]):
        raise click.BadParameter(
            f"{' '.join(f'{v:g}' for v in view)}: expected X0 < X1 and Y0 < Y1",
            param_hint="'--view'",
        )
    if start is not None and end is not None and end < start:
        raise click.BadParameter(f"--end {end:g} is before --start {start:g}")
    chosen = View(*view) if view else None
    mismatch = overlay_mismatch(trajectory, overlay) if overlay is not None else None
    if mismatch:
        click.echo(f"warning: {mismatch}", err=True)
    progress = _Progress(not quiet, unit="frames")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        if kind == ".gif":
            result = render_gif(
                trajectory, out, fps=fps, size=size, view=chosen, overlay=overlay,
                start=start, end=end, progress=progress, contacts=contacts,
            )  # fmt: skip
            line = f"{counted(result.frames, 'frame')}, {result.width}x{result.height} px"
        else:
            from .view.player import render_html

            page = render_html(
                trajectory, out, fps=fps, view=chosen, overlay=overlay, start=start, end=end,
                progress=progress, contacts=contacts,
            )  # fmt: skip
            shown = f"{counted(page.frames, 'frame')} of {counted(page.bodies, 'body', 'bodies')}"
            line = f"{shown}, {page.size / 2**20:.1f} MiB"
    except RenderError as err:
        _fail(EXIT_RUNTIME, f"error: {err}", progress)
    except KeyboardInterrupt:
        _fail(EXIT_INTERRUPTED, f"interrupted: {out} not written", progress)
    except FileExistsError:
        _fail(EXIT_RUNTIME, f"error: cannot write {out}: {out.parent} is not a folder", progress)
    except OSError as err:
        _fail(EXIT_RUNTIME, f"error: cannot write {out}: {_reason(err)}", progress)
    progress.finish()
    if not quiet:
        click.echo(f"{line} -> {out}")


@main.command()
@click.argument(
    "trajectories", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False)
)
@click.option(
    "-o",
    "--output",
    "output",
    type=click.Path(dir_okay=False),
    callback=_not_empty,
    help="Image to write, .png, .pdf or .svg [default: the first TRAJECTORY with .energy.png].",
)
def plot(trajectories: tuple[str, ...], output: str | None) -> None:
    """Plot energy and momentum over time for one or several trajectories."""
    from .view.plot import plot_observables
    from .view.render import RenderError

    first = Path(trajectories[0])
    out = Path(output) if output else first.with_name(first.stem + ".energy.png")
    if out.suffix.lower() not in (".png", ".pdf", ".svg"):
        raise click.BadParameter(
            f"{out}: the output must end in .png, .pdf or .svg", param_hint="'-o' / '--output'"
        )
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        plot_observables(list(trajectories), out)
    except RenderError as err:
        _fail(EXIT_RUNTIME, f"error: {err}")
    except FileExistsError:
        _fail(EXIT_RUNTIME, f"error: cannot write {out}: {out.parent} is not a folder")
    except OSError as err:
        _fail(EXIT_RUNTIME, f"error: cannot write {out}: {_reason(err)}")
    click.echo(
        f"{len(trajectories)} trajectories -> {out}" if len(trajectories) > 1 else f"-> {out}"
    )


@main.command()
@click.argument("scene", type=_SCENE)
@click.option(
    "-o",
    "--output",
    "out_dir",
    type=click.Path(file_okay=False),
    callback=_not_empty,
    default="out/sweep",
    show_default=True,
    help="Folder for <name>.csv, <name>.json and <name>.png.",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="As for run.")
@click.option("--dt", "dts", metavar="LIST", help="Time steps, s [default: 1/30,...,1/960].")
@click.option("--substeps", metavar="LIST", help="rbsim substeps [default: 1,4].")
@click.option("--iterations", metavar="LIST", help="rbsim iterations per substep [default: 1,4].")
@click.option("--integrator", metavar="LIST", help="rbsim integrators [default: symplectic_euler].")
@click.option(
    "--rotation",
    metavar="LIST",
    help="rbsim rotation updates [default: normalize,exact in 2D; normalize,exact,split in 3D].",
)
@click.option("--pymunk-iterations", metavar="LIST", help="pymunk iterations [default: 5,10,30].")
@click.option("--no-pymunk", is_flag=True, help="Sweep rbsim only.")
@click.option("--duration", type=_POSITIVE, help="Simulated s.")
@click.option(
    "--repeats",
    type=click.IntRange(min=1),
    default=3,
    show_default=True,
    help="Timed runs per setting (at least; short runs are repeated more).",
)
@click.option("--no-plot", is_flag=True, help="Write the table, CSV and JSON only.")
@_cluster_options
def sweep(
    scene: str,
    out_dir: str,
    overrides: tuple[str, ...],
    dts: str | None,
    substeps: str | None,
    iterations: str | None,
    integrator: str | None,
    rotation: str | None,
    pymunk_iterations: str | None,
    no_pymunk: bool,
    duration: float | None,
    repeats: int,
    no_plot: bool,
    scheduler: str | None,
    workers: int | None,
) -> None:
    """Speed against error: run SCENE over a grid of settings in rbsim and pymunk, print
    the table and write CSV, JSON and a log-log plot with each engine's Pareto front.
    With --workers or --scheduler the error runs go to a Dask cluster; the timed runs
    still run one at a time, on one worker. A 3D scene sweeps the rotation updates
    side by side over --dt, --substeps and --rotation instead (rbsim only): cost against
    the energy error and the error of a torque-free body's period against its closed form."""
    from .batch import BatchError
    from .engines.pymunk import UnsupportedScene
    from .scene.compile import ModelError
    from .scene.types import ROTATIONS
    from .tools.reference import ReferenceError
    from .tools.sweep import (
        Grid,
        PlotUnavailable,
        SweepError,
        SweepLimit,
        check_limits,
        parse_list,
        run_rotation_sweep,
        run_sweep,
    )

    lists = {
        "--dt": (dts, "dts", "dt"),
        "--substeps": (substeps, "substeps", "int"),
        "--iterations": (iterations, "iterations", "int"),
        "--integrator": (integrator, "integrators", ("symplectic_euler", "explicit_euler")),
        "--rotation": (rotation, "rotations", ROTATIONS),
        "--pymunk-iterations": (pymunk_iterations, "pymunk_iterations", "int"),
    }
    grid_args = {}
    for option, (text, name, kind) in lists.items():
        if text is not None:
            try:
                grid_args[name] = parse_list(text, kind)
            except SweepError as err:
                raise click.BadParameter(str(err), param_hint=option) from None
    if no_pymunk:
        grid_args["pymunk_iterations"] = ()
    sc = _load(scene, overrides)
    given = [option for option, (text, _, _) in lists.items() if text is not None]
    try:  # each run is a scene: held to the format's bounds on steps, dt and work
        check_limits(sc, Grid(**grid_args), duration, given)
    except SweepLimit as err:
        raise click.BadParameter(str(err), param_hint=err.option) from None
    progress = _Progress(True, unit="runs")

    def step(k: int, total: int, setting) -> None:
        progress(k, total)

    if scheduler is not None and workers is not None:
        raise click.UsageError("--scheduler and --workers exclude each other")
    try:
        with contextlib.ExitStack() as stack:
            pool = None
            if scheduler is not None or workers is not None:
                from .batch import DaskPool, dask_cluster

                cluster = stack.enter_context(dask_cluster(scheduler, workers))
                if cluster.dashboard:
                    click.echo(f"dashboard: {cluster.dashboard}", err=True)
                pool = DaskPool(cluster.client)
            sweep_fn = run_rotation_sweep if sc.world.dimension == 3 else run_sweep
            result = sweep_fn(
                sc, Grid(**grid_args), repeats=repeats, duration=duration, progress=step, pool=pool
            )
    except SweepError as err:
        _fail(2, f"Error: {err}", progress)
    except ReferenceError as err:
        _fail(EXIT_SCENE, f"{scene}: reference: {err}", progress)
    except (UnsupportedScene, ModelError) as err:
        _fail(EXIT_SCENE, f"{scene}: {err}", progress)
    except KeyboardInterrupt:
        _fail(EXIT_INTERRUPTED, "interrupted", progress)
    except BatchError as err:
        _fail(EXIT_RUNTIME, f"error: {err}", progress)
    except MemoryError:  # the sampled poses of a long run at short steps
        _fail(EXIT_RUNTIME, f"error: {scene}: out of memory (a shorter --duration?)", progress)
    progress.finish()
    click.echo(result.table())
    try:
        paths = result.write(out_dir, plot=not no_plot)
    except PlotUnavailable as err:
        click.echo(f"plot skipped: {err}", err=True)
        from .run import file_stem

        paths = {k: Path(out_dir) / f"{file_stem(result.scene)}.{k}" for k in ("csv", "json")}
    except FileExistsError:
        _fail(EXIT_RUNTIME, f"error: cannot write to {out_dir}: it is not a folder")
    except OSError as err:
        _fail(EXIT_RUNTIME, f"error: cannot write to {out_dir}: {_reason(err)}")
    click.echo("  files: " + ", ".join(str(p) for p in paths.values()))


@main.command()
@click.argument("scenes", nargs=-1, required=True, type=_SCENE)
@click.option(
    "-o",
    "--output",
    "out_dir",
    type=click.Path(file_okay=False),
    callback=_not_empty,
    default="out/batch",
    show_default=True,
    help="Folder for <run-id>.h5 and summary.csv.",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="As for run.")
@click.option(
    "--vary",
    "varies",
    multiple=True,
    metavar="KEY.PATH=LIST",
    help="Run every value of a YAML list, e.g. --vary world.dt=[0.01,0.005] (repeatable: a "
    "grid); with --samples also uniform(a,b) or normal(mu,sigma).",
)
@click.option(
    "--samples", type=click.IntRange(min=1), help="Draw N runs from the --vary values instead."
)
@click.option("--seed", type=int, help="Seed of the --samples draws [default: 0].")
@_cluster_options
@click.option(
    "--retries",
    type=click.IntRange(min=0),
    default=1,
    show_default=True,
    help="Times a failed run is sent again before it is recorded as failed.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
def batch(
    scenes: tuple[str, ...],
    out_dir: str,
    overrides: tuple[str, ...],
    varies: tuple[str, ...],
    samples: int | None,
    seed: int | None,
    scheduler: str | None,
    workers: int | None,
    retries: int,
    quiet: bool,
) -> None:
    """Run every SCENE over the grid of its --vary lists (or --samples draws) as
    independent runs on a Dask cluster; write DIR/<run-id>.h5 and DIR/summary.csv."""
    from .forkserver import start_fork_server

    if scheduler is None:  # a local cluster: its workers' fork server starts importing now
        start_fork_server()
    from .batch import (
        BatchError,
        BatchInterrupted,
        BatchInvalid,
        VaryError,
        available_cores,
        expand,
        fresh_folder,
        parse_vary,
        plan_batch,
        precheck,
        run_batch,
        starting_cluster,
    )

    started = time.perf_counter()
    if scheduler is not None and workers is not None:
        raise click.UsageError("--scheduler and --workers exclude each other")
    if samples is None and seed is not None:
        raise click.UsageError("--seed needs --samples")
    if samples is not None and not varies:
        raise click.UsageError("--samples needs at least one --vary to draw from")
    try:
        parsed = [parse_vary(v) for v in varies]
        if samples is None and any(v.dist is not None for v in parsed):
            bad = next(v for v in parsed if v.dist is not None)
            raise click.UsageError(f"--vary {bad.key}: a distribution needs --samples N")
        runs = len(scenes) * len(expand(parsed, samples, seed or 0))
    except VaryError as err:
        _fail(EXIT_SCENE, str(err))
    out = Path(out_dir)
    # A batch into a folder with no trajectory yet has every run to do: its local
    # cluster starts while the runs are checked (the check then costs no wall time),
    # once the common mistakes are ruled out (precheck: no cluster for them).
    early = scheduler is None and runs > 0 and fresh_folder(out)
    if early:
        try:
            precheck(scenes, overrides, parsed)
        except BatchInvalid as err:
            _fail(EXIT_SCENE, str(err))
    early_start = starting_cluster(None, min(workers or available_cores(), runs))
    with early_start if early else contextlib.nullcontext() as cluster:
        try:
            plan = plan_batch(scenes, overrides, parsed, samples, seed or 0)
        except (VaryError, BatchInvalid) as err:
            _fail(EXIT_SCENE, str(err))
        made = not out.exists()  # (removed again, still empty, should no run start)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            _fail(EXIT_RUNTIME, f"error: cannot write to {out}: it is not a folder")
        except OSError as err:
            _fail(EXIT_RUNTIME, f"error: cannot write to {out}: {_reason(err)}")
        progress = _BatchProgress(not quiet)

        def notify(text: str) -> None:
            if not quiet:
                click.echo(text, err=True)

        main_thread = threading.current_thread() is threading.main_thread()
        if main_thread:  # SIGTERM stops a batch like Ctrl-C
            previous = signal.signal(signal.SIGTERM, _raise_interrupt)
        try:
            result = run_batch(
                plan,
                out,
                scheduler=scheduler,
                workers=workers,
                retries=retries,
                progress=progress.runs,
                notify=notify,
                cluster=cluster,
                started=started,
            )
        except BatchInterrupted as err:
            _fail(EXIT_INTERRUPTED, str(err), progress)
        except KeyboardInterrupt:  # before the batch could record anything
            _fail(EXIT_INTERRUPTED, "interrupted before any run finished", progress)
        except BatchError as err:  # nothing ran (no scheduler there, say)
            if made:
                with contextlib.suppress(OSError):
                    out.rmdir()
            _fail(EXIT_RUNTIME, f"error: {err}", progress)
        except OSError as err:
            _fail(EXIT_RUNTIME, f"error: cannot write to {out}: {_reason(err)}", progress)
        finally:
            if main_thread:
                signal.signal(signal.SIGTERM, previous)
    progress.finish()
    shown = result.failures[:20]
    for spec, status in shown:
        click.echo(f"{spec.run_id}: {spec.label()}: {status}", err=True)
    if len(result.failures) > len(shown):
        click.echo(f"... and {len(result.failures) - len(shown)} more failed runs", err=True)
    if not quiet:
        from .scene.schema import counted

        skipped = f" ({result.skipped} already)" if result.skipped else ""
        rate = ""
        if result.ran and result.wall_time > 0:
            rate = f" ({result.ran / result.wall_time * 60:,.1f} runs/min)"
        click.echo(
            f"{counted(result.total, 'run')}: {result.complete} complete{skipped}, "
            f"{result.failed} failed "
            f"in {result.wall_time:.1f} s{rate} -> {result.paths[0]}"
        )
    if result.failed:
        sys.exit(EXIT_RUNTIME)


@main.command()
def schema() -> None:
    """Print the JSON Schema of the scene format (for editors)."""
    from .scene.schema import json_schema

    click.echo(json.dumps(json_schema(), indent=2))


if __name__ == "__main__":
    from .__main__ import entry

    entry()
