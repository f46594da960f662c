"""The threads table's host column (bench/threads.py, host_scaling): two one-thread copies
of a scene in processes of their own against one alone, so that it cannot rot; no time
asserted beyond what any host gives."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench import threads

ROOT = Path(__file__).resolve().parent.parent


def test_host_scaling_times_one_copy_against_two() -> None:
    # 2 t1 / t2: above 0 whenever both copies ran; at most 2 plus noise (two copies cannot
    # finish sooner than one, but the host's pace varies between the rounds: 4 is far
    # outside any pace change seen here). 2000 steps of the 57-body pyramid, about 0.1 s a
    # copy: 20 of the 5-body bounce (under a millisecond, within the host's jitter) once
    # gave 4.9
    ratio = threads.host_scaling(ROOT / "scenes" / "pyramid.yaml", steps=2000, rounds=1)
    assert 0.0 < ratio < 4.0


def test_a_copy_that_fails_ends_the_measure_with_an_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the copies cannot load the scene: the measure says so as soon as one has ended,
    # not after its time-out (set short, so that waiting for it fails with another message)
    monkeypatch.setattr(threads, "HOST_TIMEOUT", 60.0)
    with pytest.raises(RuntimeError, match="failed"):
        threads.host_scaling(tmp_path / "missing.yaml", steps=1, rounds=1)
