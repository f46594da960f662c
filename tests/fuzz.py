"""The fuzz driver of tests/test_fuzz.py: mutated scenes through `rbsim validate` and
`rbsim run --set world.steps=2`, all in this one process.

    python -m tests.fuzz --count 1000 --seed 18 --dir /tmp/fuzz

Each mutant starts from a shipped scene (rbsim/scenes) or a bad one (tests/bad_scenes)
and takes one to three mutations: a number set to an extreme (0, 5e-324, 1e308, 2**63,
an integer of 400 digits, nan, inf, ...), a value swapped for another type, a key
dropped, misspelt or copied next to its neighbours, a list or mapping emptied, a list
item doubled; or, on the text, a line doubled (a duplicate key) or dropped, the text cut
short, a stray character put in. Each mutant is validated as it is and with the --set of
the run, and run; the click command is called in this process (as CliRunner does) and
everything it raises is caught.

Prints one JSON report on stdout: the number of mutants and every failure (a Python
exception out of the command, an exit code the rules do not allow, a validate/run
disagreement, a run failure without its documented message), each with the mutant's
text. Before each mutant, a line "mutant N: <what>" goes to stderr (flushed), so that a
hang or a crash names the mutant it happened in.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import random
import signal
import sys
import traceback
from pathlib import Path
from typing import Any

import yaml
from click.testing import CliRunner

from rbsim import cli

ROOT = Path(__file__).parent.parent
SCENES = ROOT / "rbsim" / "scenes"
BAD = Path(__file__).parent / "bad_scenes"
# scenes of hundreds to thousands of bodies: a second per mutant would cost the budget
HEAVY = {"pyramid100.yaml", "balls_in_box.yaml"}

EXTREMES: list[Any] = [
    0,
    -1,
    0.0,
    -0.0,
    5e-324,
    1e-300,
    1e-7,
    1e-6,
    0.999,
    1e6,
    1e7,
    1e9,
    1e21,
    1e200,
    1e308,
    -1e308,
    1.7976931348623157e308,
    2**31,
    2**63,
    2**64,
    10**400,
    -(10**400),
    math.nan,
    math.inf,
    -math.inf,
]
# at the bounds (cli.md: Bounds) and around them: mutants that still validate
EDGES: list[Any] = [
    1e-6,
    1.000001e-6,
    1e-3,
    0.1,
    10,
    100,
    1000,
    1e5,
    999999.0,
    1e6,
    -1e6,
    1e-9,
    1e12,
]
OTHER_TYPES: list[Any] = [
    "text",
    "",
    "1/0",
    "1/60",
    True,
    None,
    [],
    {},
    [1, 2],
    [1, 2, 3],
    [[0, 0], [1, 0]],
    {"a": 1},
    {"circle": {"radius": 1}},
]
STRAY = ["\t", ":", "[", "]", "{", "&a", "*a", "!!python/object ", "%", "- ", "'", '"', "\x00"]

# exit codes the rules allow, and what a run's exit 1 must say (cli.md: exit codes)
VALIDATE_CODES = {0, 3}
RUN_CODES = {0, 1, 3}
RUN_FAILURES = (
    "became non-finite",
    "left the simulated region",
    "overflowed",
    "out of memory",
    "cannot write",
)
STEPS = ("--set", "world.steps=2")


class Hang(Exception):
    """One command took longer than the per-mutant limit."""


def sources() -> list[tuple[Path, str, Any]]:
    """(path, text, parsed tree or None) of every scene the mutants start from."""
    out = []
    for path in sorted(SCENES.rglob("*.yaml")) + sorted(BAD.glob("*.yaml")):
        if path.name in HEAVY:
            continue
        text = path.read_bytes().decode("utf-8", "replace")
        try:
            tree = yaml.safe_load(text)
        except yaml.YAMLError:
            tree = None
        out.append((path, text, tree if isinstance(tree, dict) else None))
    return out


def _places(node: Any, path: tuple = ()) -> list[tuple]:
    """Every (path, value) inside a parsed tree, containers included."""
    out = [(path, node)]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _places(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _places(v, path + (i,))
    return out


def _parent(tree: Any, path: tuple) -> Any:
    for part in path[:-1]:
        tree = tree[part]
    return tree


def _misspell(word: str, rng: random.Random) -> str:
    i = rng.randrange(len(word) + 1)
    how = rng.choice(("drop", "add", "swap"))
    if how == "drop" and word:
        i = min(i, len(word) - 1)
        return word[:i] + word[i + 1 :]
    if how == "swap" and len(word) > 1:
        i = min(i, len(word) - 2)
        return word[:i] + word[i + 1] + word[i] + word[i + 2 :]
    return word[:i] + rng.choice("aeiosx_") + word[i:]


def mutate_tree(tree: Any, rng: random.Random) -> str:
    """Apply one mutation to the parsed tree in place; returns what it did."""
    places = [(p, v) for p, v in _places(tree) if p]
    path, value = rng.choice(places)
    parent, key = _parent(tree, path), path[-1]
    numbers = [(p, v) for p, v in places if isinstance(v, int | float) and not isinstance(v, bool)]
    op = rng.choice(
        ("extreme", "extreme", "extreme", "type", "drop", "misspell", "empty", "double")
    )
    if op == "extreme" and numbers:
        path, value = rng.choice(numbers)
        new = rng.choice(EXTREMES if rng.random() < 0.6 else EDGES)
        _parent(tree, path)[path[-1]] = new
        return f"{_show(path)}: {_brief(value)} -> {_brief(new)}"
    if op == "type":
        new = copy.deepcopy(rng.choice(OTHER_TYPES))
        parent[key] = new
        return f"{_show(path)}: -> {_brief(new)}"
    if op == "drop":
        del parent[key]
        return f"{_show(path)}: dropped"
    if op == "misspell" and isinstance(key, str):
        parent[_misspell(key, rng)] = parent.pop(key)
        return f"{_show(path)}: key misspelt"
    if op == "empty" and isinstance(value, list | dict):
        parent[key] = type(value)()
        return f"{_show(path)}: emptied"
    if isinstance(parent, list):
        parent.insert(key, copy.deepcopy(value))
        return f"{_show(path)}: doubled"
    if isinstance(parent, dict) and isinstance(key, str):
        parent[key + rng.choice(("", "s", "_2"))] = copy.deepcopy(value)
        return f"{_show(path)}: copied next to itself"
    new = rng.choice(EXTREMES)
    parent[key] = new
    return f"{_show(path)}: -> {_brief(new)}"


def mutate_text(text: str, rng: random.Random) -> tuple[str, str]:
    """One mutation of the text itself: (new text, what it did)."""
    lines = text.split("\n")
    op = rng.choice(("double", "drop", "cut", "stray"))
    i = rng.randrange(len(lines))
    if op == "double":
        lines.insert(i, lines[i])
        return "\n".join(lines), f"line {i + 1} doubled"
    if op == "drop":
        del lines[i]
        return "\n".join(lines), f"line {i + 1} dropped"
    if op == "cut":
        at = rng.randrange(len(text) + 1)
        return text[:at], f"cut after {at} characters"
    at = rng.randrange(len(text) + 1)
    stray = rng.choice(STRAY)
    return text[:at] + stray + text[at:], f"{stray!r} put in at {at}"


def _show(path: tuple) -> str:
    return ".".join(str(p) for p in path)


def _brief(value: Any) -> str:
    """repr, with an integer of more than 20 digits by its length."""
    if isinstance(value, int) and len(str(abs(value))) > 20:
        return f"<an integer of {len(str(abs(value)))} digits>"
    return repr(value)


def make_mutant(source: tuple[Path, str, Any], rng: random.Random) -> tuple[str, list[str]]:
    """(mutant text, what was done to it) from one source scene."""
    path, text, tree = source
    done: list[str] = []
    for _ in range(rng.choice((1, 1, 2, 3))):
        if tree is not None and rng.random() < 0.8:
            new = copy.deepcopy(tree)
            try:
                what = mutate_tree(new, rng)
            except (IndexError, KeyError, TypeError, ValueError):  # nothing there to mutate
                continue
            tree, text = new, yaml.safe_dump(new, sort_keys=False, allow_unicode=True)
            done.append(what)
        else:
            text, what = mutate_text(text, rng)
            done.append(what)
            tree = None  # the text no longer matches a tree
    return text, done


def invoke(args: list[str], limit: float) -> tuple[int | None, str, str | None]:
    """Run the rbsim command line with `args` in this process: (exit code, stderr,
    traceback of an exception it let out, or None). `limit` s: a Hang after that."""
    try:
        runner = CliRunner(mix_stderr=False)  # click < 8.2 mixes the streams otherwise
    except TypeError:
        runner = CliRunner()
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        result = runner.invoke(cli.main, args, catch_exceptions=True)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    error = None
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        exc = result.exception
        error = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    try:
        stderr = result.stderr
    except ValueError:
        stderr = ""
    return result.exit_code, stderr, error


def judge(
    validate: tuple[int | None, str, str | None],
    validate_set: tuple[int | None, str, str | None],
    run: tuple[int | None, str, str | None],
) -> list[str]:
    """What is wrong with one mutant's three results (empty: nothing)."""
    problems = []
    for name, (code, stderr, error) in (
        ("validate", validate),
        ("validate --set", validate_set),
        ("run", run),
    ):
        if error is not None:
            problems.append(f"{name}: an exception got out:\n{error}")
        elif "Traceback" in stderr:
            problems.append(f"{name}: a traceback on stderr:\n{stderr}")
        allowed = RUN_CODES if name == "run" else VALIDATE_CODES
        if error is None and code not in allowed:
            problems.append(f"{name}: exit {code}, expected one of {sorted(allowed)}:\n{stderr}")
    (v_code, _, _), (r_code, r_err, _) = validate_set, run
    if v_code == 3 and r_code != 3:
        problems.append(f"run exits {r_code} on a scene that validate rejects")
    if v_code == 0 and r_code == 3:
        problems.append(f"run rejects a scene that validate accepts:\n{r_err}")
    if r_code == 1 and not (r_err.startswith("error: ") and any(s in r_err for s in RUN_FAILURES)):
        problems.append(f"run exits 1 without a documented failure:\n{r_err}")
    if r_code == 1 and len(r_err.strip().splitlines()) != 1:
        problems.append(f"run's failure is not one line:\n{r_err}")
    return problems


def main(argv: list[str] | None = None) -> int:
    """Run the mutants and print the report; 0 (the report says what failed)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=18)
    parser.add_argument("--dir", type=Path, required=True, help="folder for the mutant files")
    parser.add_argument("--limit", type=float, default=20.0, help="s per command")
    args = parser.parse_args(argv)

    def hang(signum: int, frame: Any) -> None:
        raise Hang(f"longer than {args.limit:g} s")

    signal.signal(signal.SIGALRM, hang)
    rng = random.Random(args.seed)
    pool = sources()
    good = [s for s in pool if s[0].is_relative_to(SCENES)]
    args.dir.mkdir(parents=True, exist_ok=True)
    scene, out = args.dir / "mutant.yaml", args.dir / "mutant.h5"
    failures = []
    codes: dict[str, dict[str, int]] = {"validate": {}, "run": {}}
    for k in range(args.count):
        source = rng.choice(good if rng.random() < 0.75 else pool)  # mostly runnable ones
        text, done = make_mutant(source, rng)
        print(f"mutant {k}: {source[0].relative_to(ROOT)}: {'; '.join(done)}", file=sys.stderr)
        sys.stderr.flush()
        scene.write_bytes(text.encode("utf-8", "surrogateescape"))
        out.unlink(missing_ok=True)
        v = invoke(["validate", str(scene)], args.limit)
        vs = invoke(["validate", str(scene), *STEPS], args.limit)
        r = invoke(["run", str(scene), *STEPS, "-q", "-o", str(out)], args.limit)
        for name, result in (("validate", v), ("run", r)):
            key = str(result[0])
            codes[name][key] = codes[name].get(key, 0) + 1
        problems = judge(v, vs, r)
        if problems:
            failures.append(
                {
                    "mutant": k,
                    "source": str(source[0].relative_to(ROOT)),
                    "mutations": done,
                    "problems": problems,
                    "text": text[:3000],
                }
            )
    json.dump({"mutants": args.count, "exit_codes": codes, "failures": failures}, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
