"""Every file in tests/bad_scenes/ is an invalid scene whose first line says
`# expect: <text>`: loading it must raise SceneError, every message line must name
file:line:column, and <text> must appear in the message."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from rbsim.scene import SceneError, load_scene

ROOT = Path(__file__).parent.parent
BAD = sorted((Path(__file__).parent / "bad_scenes").glob("*.yaml"))


def expected_text(path: Path) -> str:
    """The text after `# expect:` on the first line (read as bytes: some files are not UTF-8)."""
    first = path.read_bytes().split(b"\n", 1)[0].decode("ascii")
    assert first.startswith("# expect: "), f"{path.name}: first line must be '# expect: ...'"
    return first.removeprefix("# expect: ")


def test_there_are_enough_bad_scenes():
    assert len(BAD) >= 30


@pytest.mark.parametrize("path", BAD, ids=[p.stem for p in BAD])
def test_bad_scene_is_rejected_with_located_messages(path: Path):
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    lines = message.splitlines()
    assert lines, "a SceneError must say something"
    located = re.compile(rf"^{re.escape(str(path))}:\d+:\d+: \S")
    for line in lines:
        assert located.match(line), line
    assert len(lines) == len(info.value.errors)
    assert expected_text(path) in message


def _validate_command_available() -> bool:
    if not (ROOT / "rbsim" / "cli.py").exists():
        return False
    try:
        from rbsim import cli
    except Exception:  # another engineer's module that does not import yet
        return False
    return "validate" in getattr(cli.main, "commands", {})


@pytest.mark.skipif(not _validate_command_available(), reason="rbsim.cli has no validate yet")
@pytest.mark.parametrize("name", ["many_errors.yaml", "not_utf8.yaml"])
def test_cli_validate_exits_3_without_traceback(name: str):
    path = Path(__file__).parent / "bad_scenes" / name
    result = subprocess.run(
        [sys.executable, "-m", "rbsim.cli", "validate", str(path)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert result.returncode == 3, result.stderr
    assert "Traceback" not in result.stderr
    assert expected_text(path) in result.stderr
