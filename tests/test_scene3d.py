"""3D scenes (world.dimension: 3): parsing, defaults, orientations, shapes, generators,
errors with file:line:column (and exit 3 through the command line), keys of the other
dimension named as such, --set, `validate --resolved`, and the JSON Schema."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from rbsim.scene import SceneError, load_scene, load_scene_text, scene_to_dict
from rbsim.scene.geometry3d import quat_matrix
from rbsim.scene.library import scenes_dir
from rbsim.scene.schema import json_schema
from rbsim.scene.yamlsrc import load_yaml

ROOT = Path(__file__).parent.parent
SCENES_3D = sorted(scenes_dir("3d").glob("*.yaml"))

BRICK = """\
version: 1
world: {dimension: 3, dt: 0.01, duration: 1}
bodies:
  - name: brick
    position: [0, 2, 0]
    angular_velocity: [0.1, 5, 0]
    shape: {box: {size: [0.3, 0.2, 0.1]}}
"""


QUARTER_Z = "rotation: {axis: [0, 0, 1], angle: 1.5707963267948966}"  # a quarter turn about z


def load(text: str, overrides: tuple[str, ...] = ()):
    return load_scene_text(textwrap.dedent(text), "test.yaml", overrides)


def errors(text: str, overrides: tuple[str, ...] = ()) -> list[str]:
    """The message lines of the SceneError that loading ``text`` must raise."""
    with pytest.raises(SceneError) as info:
        load(text, overrides)
    return str(info.value).splitlines()


def scene_with(body: str, dimension: int = 3) -> str:
    world = "world: {dimension: 3}\n" if dimension == 3 else ""
    return f"version: 1\n{world}bodies:\n  - {body}\n"


# --- defaults ------------------------------------------------------------------------------


def test_defaults_of_a_minimal_3d_scene():
    scene = load(scene_with("{shape: {sphere: {radius: 0.5}}}"))
    w = scene.world
    assert w.dimension == 3 and w.gravity == (0.0, -9.81, 0.0)
    (b,) = scene.bodies
    assert b.position == (0.0, 0.0, 0.0) and b.velocity == (0.0, 0.0, 0.0)
    assert b.orientation == (1.0, 0.0, 0.0, 0.0) and b.angle == 0.0
    assert b.angular_velocity == (0.0, 0.0, 0.0) and b.torque == (0.0, 0.0, 0.0)
    assert b.force == (0.0, 0.0, 0.0) and b.force_point is None
    (s,) = b.shapes
    assert (s.kind, s.vertices, s.radius, s.offset) == ("sphere", ((0, 0, 0),), 0.5, (0, 0, 0))


def test_a_2d_scene_is_dimension_2_with_identity_orientation():
    scene = load("version: 1\nbodies: [{angle: 0.5, shape: {circle: {radius: 1}}}]\n")
    assert scene.world.dimension == 2 and scene.world.gravity == (0.0, -9.81)
    assert scene.bodies[0].orientation == (1.0, 0.0, 0.0, 0.0) and scene.bodies[0].angle == 0.5


def test_3d_vectors_are_read_as_given():
    scene = load(
        BRICK.replace(
            "    angular_velocity",
            "    velocity: [1, 2, 3]\n    torque: [0, 0, 1]\n    angular_velocity",
        )
    )
    b = scene.bodies[0]
    assert b.position == (0.0, 2.0, 0.0) and b.velocity == (1.0, 2.0, 3.0)
    assert b.angular_velocity == (0.1, 5.0, 0.0) and b.torque == (0.0, 0.0, 1.0)


# --- orientation and rotation --------------------------------------------------------------


def test_orientation_is_normalised_on_load():
    (b,) = load(scene_with("{orientation: [2, 0, 0, 2], shape: {sphere: {radius: 1}}}")).bodies
    h = math.sqrt(0.5)
    np.testing.assert_allclose(b.orientation, (h, 0, 0, h), rtol=1e-15)  # one division
    assert math.hypot(*b.orientation) == pytest.approx(1.0, abs=2e-16)  # unit to round-off


def test_rotation_axis_angle_gives_the_quaternion():
    text = "{rotation: {axis: [0, 0, 5], angle: 0.6}, shape: {box: {size: [1, 1, 1]}}}"
    (b,) = load(scene_with(text)).bodies
    assert b.orientation == pytest.approx((math.cos(0.3), 0, 0, math.sin(0.3)), abs=1e-16)
    # R turns x towards y by 0.6 rad
    np.testing.assert_allclose(
        quat_matrix(b.orientation) @ [1, 0, 0], [math.cos(0.6), math.sin(0.6), 0], atol=1e-15
    )


def test_a_unit_quaternion_is_kept_bit_for_bit():
    q = (0.1, 0.7, -0.1, math.sqrt(1 - 0.51))  # unit to round-off
    (b,) = load(scene_with(f"{{orientation: {list(q)}, shape: {{sphere: {{radius: 1}}}}}}")).bodies
    assert b.orientation == q


def test_shape_orientation_turns_its_corners_and_its_tensor():
    text = f"{{shape: {{box: {{size: [2, 1, 1], offset: [0, 1, 0], {QUARTER_Z}}}}}}}"
    (s,) = load(scene_with(text)).bodies[0].shapes
    corners = np.asarray(s.vertices)
    # turned a quarter about z, the 2 m side lies along y; centred at the offset
    np.testing.assert_allclose(corners.max(axis=0) - corners.min(axis=0), [1, 2, 1], atol=1e-15)
    np.testing.assert_allclose(corners.mean(axis=0), [0, 1, 0], atol=1e-15)
    assert s.size == (2.0, 1.0, 1.0) and s.offset == (0.0, 1.0, 0.0)


def test_zero_orientation_and_zero_axis_are_errors_with_their_place():
    lines = errors(scene_with("{orientation: [0, 0, 0, 0], shape: {sphere: {radius: 1}}}"))
    assert lines == [
        "test.yaml:4:19: bodies[0].orientation: a quaternion (orientation) must not be zero"
    ]
    lines = errors(
        scene_with("{rotation: {axis: [0, 0, 0], angle: 1}, shape: {sphere: {radius: 1}}}")
    )
    assert lines == [
        "test.yaml:4:23: bodies[0].rotation.axis: the axis of a rotation must not be zero"
    ]


def test_orientation_and_rotation_together_are_an_error():
    text = (
        "{orientation: [1, 0, 0, 0], rotation: {axis: [0, 0, 1], angle: 1}, "
        "shape: {sphere: {radius: 1}}}"
    )
    assert errors(scene_with(text)) == [
        "test.yaml:4:5: bodies[0]: give orientation or rotation, not both"
    ]


# --- shapes --------------------------------------------------------------------------------


def test_box_corners_and_outward_faces():
    (s,) = load(scene_with("{shape: {box: {size: [0.3, 0.2, 0.1]}}}")).bodies[0].shapes
    v = np.asarray(s.vertices)
    assert len(v) == 8 and len(s.faces) == 12
    assert {tuple(abs(x) for x in p) for p in s.vertices} == {(0.15, 0.1, 0.05)}
    for a, b, c in s.faces:  # each normal (right-hand rule) points away from the centre
        n = np.cross(v[b] - v[a], v[c] - v[a])
        assert n @ v[a] > 0


def test_convex_keeps_the_hull_points_in_order_with_outward_faces():
    points = [[0, 0, 0], [1, 0, 0], [0.2, 0.2, 0.2], [0, 1, 0], [0, 0, 1]]  # one inside
    text = f"{{shape: {{convex: {{vertices: {points}, offset: [1, 0, 0]}}}}}}"
    (s,) = load(scene_with(text)).bodies[0].shapes
    assert s.vertices == ((1, 0, 0), (2, 0, 0), (1, 1, 0), (1, 0, 1))  # offset applied
    assert len(s.faces) == 4 and s.offset == (0.0, 0.0, 0.0)
    v = np.asarray(s.vertices)
    inner = v.mean(axis=0)
    for a, b, c in s.faces:
        assert np.cross(v[b] - v[a], v[c] - v[a]) @ (v[a] - inner) > 0
    assert sorted(i for f in s.faces for i in f) == sorted([0, 1, 2, 3] * 3)


def test_convex_in_one_plane_is_an_error():
    text = "{shape: {convex: {vertices: [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]}}}"
    (line,) = errors(scene_with(text))
    assert line.startswith(
        "test.yaml:4:33: bodies[0].shape.convex.vertices: the points span no volume"
    )


def test_capsule_takes_its_offset_and_orientation_into_its_ends():
    text = (
        "{shape: {capsule: {a: [0, 0, 0], b: [1, 0, 0], radius: 0.1, offset: [0, 1, 0], "
        f"{QUARTER_Z}}}}}}}"
    )
    (s,) = load(scene_with(text)).bodies[0].shapes
    np.testing.assert_allclose(s.vertices, [[0, 1, 0], [0, 2, 0]], atol=1e-15)
    assert s.radius == 0.1


def test_plane_normal_is_normalised_and_static_only():
    text = "{type: static, shape: {plane: {normal: [0, 3, 4], offset: 2}}}"
    (s,) = load(scene_with(text)).bodies[0].shapes
    assert s.normal == pytest.approx((0, 0.6, 0.8), abs=1e-16)
    assert s.vertices == (pytest.approx((0, 1.2, 1.6), abs=1e-15),)
    lines = errors(scene_with("{type: kinematic, shape: {plane: {}}}"))
    assert lines == [
        "test.yaml:4:38: bodies[0].shape.plane: a plane is for static bodies only "
        "(this body is kinematic): it is an unbounded half-space"
    ]


# --- generators ----------------------------------------------------------------------------


def test_stack_grows_along_y_from_its_origin():
    scene = load(
        scene_with("stack: {count: 3, size: [1, 0.5, 2], spacing: 0.1, origin: [1, 0.25, 2]}")
    )
    assert [b.name for b in scene.bodies] == ["stack[0]", "stack[1]", "stack[2]"]
    assert [b.position for b in scene.bodies] == [(1, 0.25, 2), (1, 0.85, 2), (1, 1.45, 2)]
    assert scene.bodies[0].shapes[0].size == (1.0, 0.5, 2.0)


def test_pyramid_has_square_layers_centred_over_its_origin():
    scene = load(scene_with("pyramid: {base: 3, size: [1, 1, 1]}"))
    assert len(scene.bodies) == 9 + 4 + 1
    names = [b.name for b in scene.bodies]
    assert names[:3] == ["pyramid[0,0,0]", "pyramid[0,0,1]", "pyramid[0,0,2]"]
    assert names[-1] == "pyramid[2,0,0]"
    by_name = {b.name: b.position for b in scene.bodies}
    assert by_name["pyramid[0,0,0]"] == (-1.0, 0.5, -1.0)
    assert by_name["pyramid[1,1,0]"] == (0.5, 1.5, -0.5)
    assert by_name["pyramid[2,0,0]"] == (0.0, 2.5, 0.0)


def test_grid_places_i_j_k_along_x_y_z():
    text = (
        "grid: {count: [2, 3, 4], spacing: [1, 2, 3], origin: [0, 1, 0], velocity: [0, 0, 1], "
        "shape: {sphere: {radius: 0.4}}}"
    )
    scene = load(scene_with(text))
    assert len(scene.bodies) == 24
    by_name = {b.name: b for b in scene.bodies}
    assert by_name["grid[1,2,3]"].position == (1.0, 5.0, 9.0)
    assert by_name["grid[0,0,0]"].velocity == (0.0, 0.0, 1.0)
    assert by_name["grid[0,0,0]"].angular_velocity == (0.0, 0.0, 0.0)


def test_generator_bounds_apply_in_3d():
    (line,) = errors(
        scene_with(
            "grid: {count: [5, 5, 5], spacing: [0.1, 0.1, 0.1], shape: {sphere: {radius: 1}}}"
        )
    )
    assert "each overlaps up to 124 others" in line and "at most its 26 neighbours" in line
    (line,) = errors(scene_with("stack: {count: 3, spacing: 600000}"))
    assert "places bodies" in line and "beyond the 1e6 m" in line


# --- errors, dimensions --------------------------------------------------------------------


def test_2d_keys_in_a_3d_scene_are_named_as_such():
    lines = errors(scene_with("{angle: 0.1, position: [0, 1], shape: {circle: {radius: 1}}}"))
    assert lines == [
        "test.yaml:4:6: bodies[0].angle: `angle` is a 2D key: a 3D scene gives "
        "orientation: [w,x,y,z] or rotation: {axis, angle}",
        "test.yaml:4:28: bodies[0].position: expected [x, y, z], 3 numbers, got a list of 2 "
        "items; [x, y] is for a 2D scene, this one is 3D (world.dimension: 3)",
        "test.yaml:4:44: bodies[0].shape.circle: `circle` is a 2D shape: a 3D scene has "
        "sphere: {radius}",
    ]
    (line,) = errors(scene_with("{shape: {polygon: {vertices: [[0, 0], [1, 0], [0, 1]]}}}"))
    assert "`polygon` is a 2D shape: a 3D scene has convex" in line


def test_3d_keys_in_a_2d_scene_are_named_as_such():
    text = "{orientation: [1, 0, 0, 0], position: [0, 1, 0], shape: {sphere: {radius: 1}}}"
    lines = errors(scene_with(text, dimension=2))
    assert lines == [
        "test.yaml:3:6: bodies[0].orientation: `orientation` is a 3D key (for a scene with "
        "world.dimension: 3): a 2D scene gives angle: (rad)",
        "test.yaml:3:43: bodies[0].position: expected [x, y], 2 numbers, got a list of 3 "
        "items; a 3-vector is for a 3D scene (world.dimension: 3)",
        "test.yaml:3:62: bodies[0].shape.sphere: `sphere` is a 3D shape (for a scene with "
        "world.dimension: 3): a 2D scene has circle: {radius}",
    ]


def test_dimension_must_be_2_or_3():
    (line,) = errors(
        "version: 1\nworld: {dimension: 4}\nbodies: [{shape: {circle: {radius: 1}}}]\n"
    )
    assert line == "test.yaml:2:20: world.dimension: must be 2 or 3, got 4"


@pytest.mark.parametrize("dimension", ["4", '"3"', "3.0", "true"])
def test_a_wrong_dimension_is_the_only_dimension_error(dimension: str) -> None:
    # read as the default 2D, every 3-vector and 3D shape was wrong too: not reported
    lines = errors(
        f"version: 1\nworld: {{dimension: {dimension}, dt: -1}}\nbodies:\n"
        "  - {position: [0, 1, 0], velocity: [0, 0, 1], shape: {sphere: {radius: 0.1}}}\n"
        "  - {position: [0, 1], shape: {circle: {radius: 0.1}}}\n"
    )
    assert len(lines) == 2, lines
    assert lines[0].startswith("test.yaml:2:20: world.dimension: ")
    assert "world.dt: must be between" in lines[1]  # whatever the dimension, still wrong


def test_3d_bounds_are_the_2d_ones():
    (line,) = errors(scene_with("{position: [0, 0, 2e6], shape: {sphere: {radius: 1}}}"))
    assert line.endswith("bodies[0].position[2]: must be between -1e6 and 1e6, got 2000000")
    (line,) = errors(scene_with("{shape: {sphere: {radius: 1e-7}}}"))
    assert "must be between 1e-6 and 1e6" in line
    (line,) = errors(scene_with("{force: [0, 1e9, 0], shape: {sphere: {radius: 0.1}}}"))
    assert "bodies[0].force: accelerates the body by" in line
    lines = errors(BRICK, ("solver.substeps=1000", "solver.iterations=1001"))
    assert "shape-iterations, more than the 62,500 that keep one step in 3D" in lines[0]
    # the 3D work bound is 1/16 of the 2D one: 62,500 shape-iterations pass, one more not
    assert load(BRICK, ("solver.substeps=62500",)).solver.substeps == 62500
    (line,) = errors(BRICK, ("solver.substeps=62501",))
    assert "= 62,501 shape-iterations, more than the 62,500" in line


@pytest.mark.parametrize("name", ["3d_angle_key.yaml", "3d_sphere_in_2d_scene.yaml"])
def test_cli_validate_exits_3_with_the_place(name: str):
    path = ROOT / "tests" / "bad_scenes" / name
    result = subprocess.run(
        [sys.executable, "-m", "rbsim", "validate", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 3, result.stderr
    assert "Traceback" not in result.stderr
    expected = path.read_text().splitlines()[0].removeprefix("# expect: ")
    assert f"{path}:" in result.stderr and expected in result.stderr
    assert result.stderr.split(f"{path}:")[1].split(":")[0].isdigit()  # the line


# --- --set and the resolved scene ----------------------------------------------------------


def test_set_works_by_body_name_and_generator_index():
    text = (
        BRICK + "  - grid: {count: [1, 1, 1], spacing: [1, 1, 1], shape: {sphere: {radius: 0.1}}}\n"
    )
    scene = load(
        text,
        (
            "bodies.brick.angular_velocity=[0, 0, 3]",
            "bodies.brick.rotation={axis: [1, 0, 0], angle: 0.2}",
            "bodies.1.grid.count=[2, 1, 3]",
            "world.gravity=[0, 0, -1]",
        ),
    )
    assert scene.bodies[0].angular_velocity == (0.0, 0.0, 3.0)
    assert scene.bodies[0].orientation == pytest.approx((math.cos(0.1), math.sin(0.1), 0, 0))
    assert len(scene.bodies) == 1 + 6 and scene.world.gravity == (0.0, 0.0, -1.0)
    # a --set of rotation removes the body's orientation (the two exclude each other)
    again = load(
        BRICK.replace("    position", "    orientation: [1, 0, 0, 0]\n    position"),
        ("bodies.brick.rotation={axis: [0, 1, 0], angle: 0.4}",),
    )
    assert again.bodies[0].orientation == pytest.approx((math.cos(0.2), 0, math.sin(0.2), 0))


def test_set_of_a_2d_vector_in_3d_names_the_override():
    with pytest.raises(SceneError) as info:
        load(BRICK, ("bodies.brick.velocity=[1, 0]",))
    assert str(info.value) == (
        "test.yaml: --set bodies.brick.velocity: bodies[0].velocity: expected [x, y, z], 3 "
        "numbers, got a list of 2 items; [x, y] is for a 2D scene, this one is 3D "
        "(world.dimension: 3)"
    )


def test_resolved_scene_round_trips_in_3d():
    text = """\
    version: 1
    world: {dimension: 3, dt: 0.01, steps: 5}
    materials: {steel: {density: 7800}}
    bodies:
      - {name: ground, type: static, shape: {plane: {normal: [0, 1, 0], offset: -1}}}
      - name: thing
        rotation: {axis: [1, 2, 3], angle: 0.4}
        angular_velocity: [1, 2, 3]
        force: [0, 1, 0]
        force_point: [0.1, 0, 0]
        material: steel
        shapes:
          - {box: {size: [1, 0.5, 0.2], rotation: {axis: [0, 1, 0], angle: 0.3}}}
          - {sphere: {radius: 0.2, offset: [0.5, 0, 0]}}
          - {capsule: {a: [0, 0, 0], b: [0, 1, 0], radius: 0.05, offset: [0, 0, 1]}}
          - convex:
              vertices: [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
              rotation: {axis: [1, 0, 0], angle: 1}
      - pyramid: {base: 2}
    """
    scene = load(text)
    data = scene_to_dict(scene)
    json.dumps(data)  # plain data
    assert data["world"]["dimension"] == 3 and "angle" not in data["bodies"][1]
    assert len(data["bodies"]) == 2 + 5
    again = load_scene_text(yaml.safe_dump(data, sort_keys=False), "test.yaml")
    assert replace(again, source="") == replace(scene, source="")


def test_cli_validate_resolved_prints_the_3d_scene(tmp_path: Path):
    path = tmp_path / "brick.yaml"
    path.write_text(BRICK)
    result = subprocess.run(
        [sys.executable, "-m", "rbsim", "validate", "--resolved", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    data = yaml.safe_load(result.stdout)
    assert data["world"]["dimension"] == 3 and data["world"]["gravity"] == [0, -9.81, 0]
    (brick,) = data["bodies"]
    assert brick["orientation"] == [1, 0, 0, 0] and brick["angular_velocity"] == [0.1, 5, 0]
    assert brick["shapes"][0]["box"]["size"] == [0.3, 0.2, 0.1]


# --- the shipped 3D scenes and the JSON Schema ---------------------------------------------


def test_there_are_3d_scenes():
    names = {p.stem for p in SCENES_3D}
    assert {"tumbling_brick", "symmetric_top", "thrown_compound", "generators"} <= names


@pytest.mark.parametrize("path", SCENES_3D, ids=[p.stem for p in SCENES_3D])
def test_3d_scene_loads_and_names_the_schema(path: Path):
    scene = load_scene(path)
    assert scene.world.dimension == 3 and scene.name == path.stem
    assert (
        path.read_text().splitlines()[0]
        == "# yaml-language-server: $schema=../../rbsim-schema.json"
    )


def test_json_schema_holds_each_dimension_to_its_own_format():
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads(json.dumps(json_schema()))
    jsonschema.Draft202012Validator.check_schema(schema)
    assert "body3d" in schema["$defs"] and "shape3d" in schema["$defs"]
    assert set(schema["$defs"]["shape3d"]["properties"]) >= {"sphere", "capsule", "convex", "plane"}
    for path in SCENES_3D:
        data, _, _ = load_yaml(path.read_text())
        jsonschema.validate(json.loads(json.dumps(data)), schema)
    validator = jsonschema.Draft202012Validator(schema)
    flat_in_3d = {
        "version": 1,
        "world": {"dimension": 3, "gravity": [0, -9.81]},
        "bodies": [{"shape": {"circle": {"radius": 1}}}],
    }
    assert len(list(validator.iter_errors(flat_in_3d))) >= 2  # gravity, circle
    deep_in_2d = {
        "version": 1,
        "bodies": [{"position": [0, 0, 0], "shape": {"sphere": {"radius": 1}}}],
    }
    assert list(validator.iter_errors(deep_in_2d))


def test_a_force_off_the_centre_is_bounded_by_its_torque():
    # 1 kg unit cube: I = 1/6 kg·m², the least radius of gyration √(1/6) m; a force of
    # 1e5 N (1e5 m/s², inside the bound) 10 m off the centre gives a torque of 1e6 N·m,
    # which accelerates the points at that radius by 1e6/√(1/6) = 2.4e6 m/s²
    text = "{force: [0, 1e5, 0], force_point: [10, 0, 0], shape: {box: {size: [1, 1, 1]}}}"
    (line,) = errors(scene_with(text))
    assert "bodies[0].force_point: the torque accelerates the body's points by 2.45e6" in line
    assert "least radius of gyration 0.408 m" in line
    load(scene_with(text.replace("[10, 0, 0]", "[0.1, 0, 0]")))  # 1e4 N·m: 2.4e4 m/s², fine


def _bounds_row(what: str) -> str:
    """The row of cli.md's Bounds table that starts with `what`."""
    text = (Path(__file__).resolve().parents[1] / "cli.md").read_text()
    return next(line for line in text.splitlines() if line.startswith(f"| {what}"))


@pytest.mark.parametrize(
    ("dimension", "shape", "valid"),
    [
        (2, "{segment: {a: [0, 0], b: [1, 0], radius: 0}}", True),
        (2, "{segment: {a: [0, 0], b: [1, 0], radius: 5.0e-7}}", False),
        (2, "{segment: {a: [0, 0], b: [1, 0], radius: 1.0e-6}}", True),
        (3, "{capsule: {a: [0, 0, 0], b: [1, 0, 0], radius: 0}}", False),
        (3, "{capsule: {a: [0, 0, 0], b: [1, 0, 0], radius: 1.0e-6}}", True),
    ],
)
def test_bounds_table_states_the_radius_rule_the_validator_applies(dimension, shape, valid):
    """cli.md's sizes row said a capsule's radius may be 0; the 3D validator (and
    format.md) require 1e-6 m. Only a 2D segment's radius may be 0 (a thin segment)."""
    row = _bounds_row("sizes:")
    assert "a 2D segment's `radius` (which may also be 0" in row
    assert "a 3D capsule's `radius` (never 0)" in row
    ground = "{name: g, type: static, " + f"shape: {shape}" + "}"
    text = f"version: 1\nworld: {{dimension: {dimension}, steps: 1}}\nbodies:\n  - {ground}\n"
    if valid:
        load_scene_text(text)
    else:
        with pytest.raises(SceneError, match="radius"):
            load_scene_text(text)
