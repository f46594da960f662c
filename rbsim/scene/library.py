"""The scenes that ship with rbsim, as package data (rbsim/scenes/; the repository's
top-level `scenes` is a link to it, so `scenes/pyramid.yaml` works from a checkout).

The tools find their scenes here (hard cases in hard/, the work-precision scenes in
reference/, compare/), never by a path relative to a module's file.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def scenes_dir(*parts: str) -> Path:
    """The folder of rbsim's scenes, or a file or folder inside it (`parts`), on disk."""
    root = Path(str(resources.files("rbsim").joinpath("scenes")))
    return root.joinpath(*parts)
