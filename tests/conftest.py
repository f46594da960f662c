"""Shared helpers: scenes from inline YAML, run to a trajectory in a temp folder."""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from rbsim import cli
from rbsim.io.trajectory import Trajectory, load_trajectory
from rbsim.scene import Scene, load_scene_text

# A child `python -m rbsim` as this interpreter runs: with -S and -P where this process
# has them, so that it imports the same rbsim. `make sanitize` runs pytest with both, its
# sanitized engine on PYTHONPATH; without them a child took the editable install's
# engine (its .pth file), another build, and a run it stopped and the test resumed here
# differed from the reference by a bit of a body's ω (1e-15 rad/s)
PYTHON = [
    sys.executable,
    *(["-S"] if sys.flags.no_site else []),
    *(["-P"] if sys.flags.safe_path else []),
]


def scene_from(text: str, overrides: tuple[str, ...] = ()) -> Scene:
    """A resolved scene from inline YAML (dedented)."""
    return load_scene_text(textwrap.dedent(text), "inline.yaml", overrides)


def vector(dimension: int, *xyz: float) -> str:
    """A scene's vector of `dimension` components, the first of xyz, as YAML: one
    builder writes a scene in 2D and 3D (x, y in 2D; x, y, z in 3D)."""
    return "[" + ", ".join(str(v) for v in xyz[:dimension]) + "]"


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


def TAKE_CTRL_C() -> None:  # noqa: N802 - a constant's name: a child's preexec_fn
    """Run in a child before it starts (subprocess's preexec_fn): SIGINT's default action,
    which Python turns into KeyboardInterrupt (a shell running the tests in the background
    may ignore SIGINT, and the child would inherit that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def python_child(script: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """`script` (dedented) run by this Python (PYTHON) in a process of its own that takes
    Ctrl-C (TAKE_CTRL_C), its output captured as text; at most 120 s."""
    return subprocess.run(
        [*PYTHON, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        preexec_fn=TAKE_CTRL_C,
    )


# Python source of blas_threads(): the threads numpy's OpenBLAS runs on in the process
# that calls it (None where numpy's BLAS is not OpenBLAS), for a child's script
BLAS_THREADS = """
def blas_threads():
    import ctypes
    paths = {l.split()[-1] for l in open("/proc/self/maps") if "openblas" in l}
    for path in sorted(paths):
        lib = ctypes.CDLL(path)
        for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads"):
            if hasattr(lib, name):
                return getattr(lib, name)()
    return None
"""


@contextlib.contextmanager
def started_rbsim(*args: str | Path, env: dict | None = None) -> Iterator[subprocess.Popen]:
    """`python -m rbsim ARGS` as a child process (text pipes) that takes Ctrl-C (a shell
    running the tests in the background may ignore SIGINT, and Python would then too);
    killed on leaving if it still runs."""
    proc = subprocess.Popen(
        [*PYTHON, "-m", "rbsim", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=TAKE_CTRL_C,
        env=env,
    )
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


# ---------------------------------------------------------------------------------------
# The player pages in a real browser (Debian's chromium driven by playwright)
# ---------------------------------------------------------------------------------------

CHROMIUM = "/usr/bin/chromium"
NO_BROWSER = (
    "needs Debian's chromium at /usr/bin/chromium (apt-get install -y chromium) and the "
    "playwright package (pip install -e '.[test]'); .ci/run installs both"
)


def _browser():
    """A playwright Browser on Debian's chromium, or a pytest skip saying what to install."""
    if not os.path.exists(CHROMIUM) and not shutil.which("chromium"):
        pytest.skip(NO_BROWSER)
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip(NO_BROWSER)
    manager = sync_playwright().start()
    browser = manager.chromium.launch(
        executable_path=CHROMIUM if os.path.exists(CHROMIUM) else shutil.which("chromium"),
        args=[
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
        ],
    )
    return manager, browser


@pytest.fixture(scope="module")
def browser():
    manager, b = _browser()
    yield b
    b.close()
    manager.stop()


def open_page(browser, page_path: Path):
    """A page on `page_path` with its console errors and uncaught exceptions collected."""
    page = browser.new_page(viewport={"width": 800, "height": 600})
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(page_path.as_uri())
    page.wait_for_function("window.rbsimPlayer && window.rbsimPlayer.ready", timeout=20000)
    return page, errors


def canvas_rgb(page, x: float, y: float) -> np.ndarray:
    """The colour of the canvas around CSS pixel (x, y) from its top-left corner:
    3 x 3 pixels of a screenshot."""
    from PIL import Image

    box = page.locator("#canvas").bounding_box()
    png = page.screenshot(
        clip={"x": box["x"] + x - 1, "y": box["y"] + y - 1, "width": 3, "height": 3}
    )
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).reshape(-1, 3)
