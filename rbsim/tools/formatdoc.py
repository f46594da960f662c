"""The key tables of docs/format.md, made from the scene format's own definition.

`python -m rbsim.tools.formatdoc` rewrites the part of docs/format.md between its two
markers with a table of every key of a 2D scene and one of every key of a 3D scene
(rbsim.scene.schema: the same definitions that validate scenes and make the JSON
Schema), so that the reference cannot drift from what `rbsim validate` accepts; a test
checks that the file is current. `--check` only says whether it is.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..scene.schema import NO_DEFAULT, REQUIRED, SCENES_BY_DIMENSION, Key

FORMAT_DOC = Path(__file__).resolve().parents[2] / "docs" / "format.md"
BEGIN = "<!-- keys: made by `python -m rbsim.tools.formatdoc` from rbsim/scene/schema.py -->"
END = "<!-- end of the keys -->"

# a scalar kind's words in the table
KINDS = {
    "number": "number",
    "integer": "integer",
    "string": "text",
    "file_name": "text (a file name)",
    "fraction": 'number or "a/b"',
    "vec2": "[x, y]",
    "vec3": "[x, y, z]",
    "quat": "[w, x, y, z]",
    "int2": "[i, j] integers",
    "int3": "[i, j, k] integers",
    "points": "[[x, y], ...]",
    "points3": "[[x, y, z], ...]",
    "object": "mapping",
    "map_of": "mapping of names",
    "list_of": "list",
    "entry": "mapping",
}


def _number(x: float) -> str:
    return f"{x:g}"


def _bounds(key: Key) -> str:
    """A number's or vector's bounds, in words."""
    parts = []
    if key.gt is not None:
        parts.append(f"> {_number(key.gt)}")
    if key.ge is not None:
        parts.append(f">= {_number(key.ge)}")
    if key.le is not None:
        parts.append(f"<= {_number(key.le)}")
    if key.within is not None:
        parts.append(f"\\|x\\| <= {_number(key.within)}")
    return ", ".join(parts)


def _kind(key: Key) -> str:
    """What a value of `key` is."""
    if key.kind == "enum":
        return " \\| ".join(f"`{c}`" for c in key.choices)
    if key.kind == "selection":
        return " \\| ".join(f"`{c}`" for c in key.choices) + " \\| list of names"
    words = KINDS.get(key.kind, key.kind)
    if key.kind == "integer" and key.choices:
        words = " \\| ".join(str(c) for c in key.choices)
    bounds = _bounds(key)
    if key.kind in ("list_of", "points", "points3") and (key.min_items or key.max_items):
        if key.max_items is None:
            items = f"at least {key.min_items}"
        else:
            items = f"{key.min_items} to {key.max_items} items"
        bounds = ", ".join(b for b in (bounds, items) if b)
    return f"{words} ({bounds})" if bounds else words


def _default(key: Key) -> str:
    if key.default is REQUIRED:
        return "required"
    if key.default is NO_DEFAULT or key.kind in ("object", "entry"):
        return ""
    value: Any = key.default
    if isinstance(value, tuple):
        value = list(value)
    if value == {} or value == []:
        return ""
    if isinstance(value, float):
        return f"`{_number(value)}`"
    return f"`{value}`"


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def rows(key: Key, path: str) -> Iterator[tuple[str, str, str, str]]:
    """(key path, what its value is, default, description) of `key` at `path` and of
    every key under it, depth first."""
    if path:
        yield path, _kind(key), _default(key), _cell(key.description)
    if key.kind == "object":
        for name, child in key.fields.items():
            yield from rows(child, f"{path}.{name}" if path else name)
    elif key.kind == "map_of" and key.item is not None:
        yield from rows(key.item, f"{path}.NAME")
    elif key.kind == "list_of" and key.item is not None:
        index = "ijk"[min(path.count("["), 2)]  # bodies[i].shapes[j]
        yield from rows(key.item, f"{path}[{index}]")
    elif key.kind == "entry":
        if key.item is not None:
            for name, child in key.item.fields.items():
                yield from rows(child, f"{path}.{name}")
        for name, variant in key.variants.items():
            yield from rows(variant, f"{path}.{name}")


def table(dimension: int) -> str:
    """The markdown table of every key of a scene in `dimension` (2 or 3)."""
    lines = ["| key | value | default | meaning |", "|---|---|---|---|"]
    for path, kind, default, text in rows(SCENES_BY_DIMENSION[dimension], ""):
        lines.append(f"| `{path}` | {kind} | {default} | {text} |")
    return "\n".join(lines)


def generated() -> str:
    """The part of docs/format.md between the markers (markers included)."""
    return "\n\n".join(
        [
            BEGIN,
            "### Every key of a 2D scene",
            table(2),
            "### Every key of a 3D scene (`world.dimension: 3`)",
            table(3),
            END,
        ]
    )


def current(text: str) -> str:
    """`text` (docs/format.md) with its generated part made anew."""
    head, sep, rest = text.partition(BEGIN)
    _old, sep2, tail = rest.partition(END)
    if not sep or not sep2:
        raise ValueError(f"{FORMAT_DOC}: the markers {BEGIN!r} and {END!r} are missing")
    return head + generated() + tail


def main(argv: list[str] | None = None) -> int:
    """Rewrite docs/format.md's key tables (or, with --check, exit 1 if they are stale)."""
    parser = argparse.ArgumentParser(prog="python -m rbsim.tools.formatdoc", description=__doc__)
    parser.add_argument("--check", action="store_true", help="only say whether it is current")
    args = parser.parse_args(argv)
    text = FORMAT_DOC.read_text(encoding="utf-8")
    made = current(text)
    if args.check:
        if made != text:
            print(f"{FORMAT_DOC} is stale: python -m rbsim.tools.formatdoc", file=sys.stderr)
            return 1
        return 0
    if made != text:
        FORMAT_DOC.write_text(made, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
