"""Fuzzing the front: 1,000 mutated scenes (tests/fuzz.py; 2D and, in two of five, 3D)
through `rbsim validate` and `rbsim run --set world.steps=2` in one subprocess.
Allowed: exit 0 or 3 from validate,
0, 1 with a documented one-line failure, or 3 from run, and run rejecting exactly what
validate rejects; never an exception out of a command, a signal, or a hang.

RBSIM_FUZZ_COUNT and RBSIM_FUZZ_SEED change the number of mutants and the seed (the
default seed makes the run repeatable).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from .fuzz import judge

ROOT = Path(__file__).parent.parent
COUNT = int(os.environ.get("RBSIM_FUZZ_COUNT", "1000"))
SEED = int(os.environ.get("RBSIM_FUZZ_SEED", "18"))
# a hang guard, not a timing: 1,000 mutants take 30-60 s on one shared core
TIMEOUT = 600


def _last_mutant(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.startswith("mutant ")]
    return lines[-1] if lines else "(before the first mutant)"


def test_mutated_scenes_never_crash_hang_or_disagree(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "tests.fuzz", "--count", str(COUNT), "--seed", str(SEED)]
    try:
        proc = subprocess.run(
            [*command, "--dir", str(tmp_path)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
        )
    except subprocess.TimeoutExpired as err:
        stderr = err.stderr.decode() if isinstance(err.stderr, bytes) else err.stderr or ""
        pytest.fail(f"the fuzz driver hung ({TIMEOUT} s) in {_last_mutant(stderr)}")
    assert proc.returncode >= 0, (
        f"killed by signal {-proc.returncode} in {_last_mutant(proc.stderr)}"
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout)
    assert report["mutants"] == COUNT
    assert report["from_3d"] >= COUNT * 3 // 10  # 3D scenes in two of five, and bad ones
    # the mutants reach both sides: some run, most are rejected
    assert report["exit_codes"]["run"].get("0", 0) >= COUNT // 20, report["exit_codes"]
    assert report["exit_codes"]["validate"].get("3", 0) >= COUNT // 2, report["exit_codes"]
    shown = [
        f"mutant {f['mutant']} of {f['source']} ({'; '.join(f['mutations'])}):\n"
        + "\n".join(f["problems"])
        + f"\n--- its text ---\n{f['text']}"
        for f in report["failures"][:5]
    ]
    assert not report["failures"], f"{len(report['failures'])} failures; the first:\n\n" + (
        "\n\n".join(shown)
    )


# the judge itself: it must see what the fuzz test is there to catch --------------------------


def _ok(code: int) -> tuple[int, str, None]:
    return code, "", None


def test_the_judge_flags_an_exception_a_bad_code_and_a_disagreement() -> None:
    assert judge(_ok(0), _ok(0), _ok(0)) == []
    assert judge(_ok(3), _ok(3), _ok(3)) == []
    ran_into = (1, "error: s.yaml: the state of body 'b' became non-finite at step 1\n", None)
    assert judge(_ok(0), _ok(0), ran_into) == []
    crash = (1, "", "Traceback (most recent call last):\n  ZeroDivisionError\n")
    assert any("exception" in p for p in judge(_ok(0), _ok(0), crash))
    assert any("exit 2" in p for p in judge(_ok(2), _ok(0), _ok(0)))
    assert any("validate accepts" in p for p in judge(_ok(0), _ok(0), _ok(3)))
    assert any("validate rejects" in p for p in judge(_ok(3), _ok(3), _ok(0)))
    undocumented = (1, "error: something else\n", None)
    assert any("documented" in p for p in judge(_ok(0), _ok(0), undocumented))
