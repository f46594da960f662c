"""Scenes: YAML text -> a validated, resolved Scene -> the model's flat arrays.

The bottom of the front: this package imports nothing else of rbsim.

- types: the vocabularies (shape kinds, body types, integrators, rotations, mixing
  rules), defined once.
- yamlsrc: YAML with the file:line:column of every node.
- schema: the format as data; validation and the JSON Schema come from it.
- resolve: the resolver (defaults, materials, generators) into the Scene dataclasses.
- mass: mass, centre of mass and moment of inertia from shapes and density.
- mass3d: the same in 3D: volume, centre of mass and full inertia tensor per shape kind,
  compounds by the parallel-axis theorem, principal axes.
- geometry3d: quaternions, box corners and faces, convex hulls (qhull via scipy).
- compile: Scene -> Model and State arrays, the only flattener (2D and 3D).
"""

from .resolve import (
    Body,
    Material,
    Output,
    Scene,
    SceneError,
    SceneIssue,
    Shape,
    Solver,
    World,
    apply_overrides,
    box_corners,
    convex_ccw,
    load_scene,
    load_scene_text,
    override_lines,
    scene_to_dict,
)

__all__ = [
    "Body",
    "Material",
    "Output",
    "Scene",
    "SceneError",
    "SceneIssue",
    "Shape",
    "Solver",
    "World",
    "apply_overrides",
    "box_corners",
    "convex_ccw",
    "load_scene",
    "load_scene_text",
    "override_lines",
    "scene_to_dict",
]
