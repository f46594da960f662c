"""Contact points in the trajectory (output.contacts: points): what the engine records
per frame, how the writer lays the rows out and grows them, how load_trajectory and
`rbsim info` read them, and that a run which does not ask records nothing."""

from __future__ import annotations

import numpy as np
import pytest

import rbsim
from rbsim.io.trajectory import CONTACT_BLOCK_ROWS, CONTACT_FILE_ROWS, summarize
from rbsim.run import resume_run, run_scene
from rbsim.scene import load_scene, load_scene_text
from rbsim.scene.library import scenes_dir

from .conftest import vector

G = 9.81  # m/s², the default gravity's magnitude

BOX_ON_PLANE = """
version: 1
world: {dimension: 3, dt: 0.01, steps: 60}
output: {contacts: points}
bodies:
  - {name: ground, type: static, shape: {plane: {normal: [0, 1, 0], offset: 0}}}
  - {name: box, position: [0.3, 0.5, -0.2], density: 1000, shape: {box: {size: [1, 1, 1]}}}
"""

BOX_ON_SEGMENT = """
version: 1
world: {dt: 0.01, steps: 60}
output: {contacts: points}
bodies:
  - {name: ground, type: static, shape: {segment: {a: [-5, 0], b: [5, 0]}}}
  - {name: box, position: [0.3, 0.5], density: 1000, shape: {box: {size: [1, 1]}}}
"""


def pile(tmp_path, name: str, *sets: str):  # noqa: ANN201 - a Trajectory
    """The shipped collapsing pile, its first 2 s, with `sets` (--set lines)."""
    path = scenes_dir("3d") / "collapsing_pile.yaml"
    scene = load_scene(path, ["world.duration=2", *sets])
    out = tmp_path / f"{name}.h5"
    run_scene(scene, out)
    return out


def test_a_box_resting_on_a_plane_records_its_four_corners_with_normals_up() -> None:
    tr = rbsim.run(BOX_ON_PLANE)
    c = tr.contacts
    assert c is not None
    assert c.count[0] == 0  # step 0: nothing has been stepped, no contact yet
    assert np.array_equal(c.count[1:], np.full(len(tr.step) - 1, 4))
    assert np.array_equal(c.count, tr.observables["contact_count"])
    assert np.array_equal(c.start, np.concatenate([[0], np.cumsum(c.count)[:-1]]))
    rows = c.frame(len(tr.step) - 1)
    ground, box = tr.body("ground"), tr.body("box")
    assert np.array_equal(c.body[rows], np.tile([ground, box], (4, 1)))
    # the normal points from the first body (the ground) into the second: straight up
    assert np.array_equal(c.normal[rows], np.tile([0.0, 1.0, 0.0], (4, 1)))
    p = c.position[rows]
    # at the plane: the midpoint of the box's face and the plane, half the soft
    # contact's sag below it (tens of µm for a 1 t box at h = 2.5 ms)
    assert np.all(np.abs(p[:, 1]) < 1e-4)
    # under the box's four bottom corners, which do not move sideways (round-off)
    corners = {(round(x, 9), round(z, 9)) for x in (-0.2, 0.8) for z in (-0.7, 0.3)}
    assert {(round(x, 9), round(z, 9)) for x, z in p[:, [0, 2]]} == corners
    # the four normal forces carry the box's weight (a box at rest: to round-off)
    weight = 1000.0 * G
    assert abs(c.force[rows].sum() - weight) < 1e-9 * weight


def test_2d_records_the_same_way() -> None:
    tr = rbsim.run(BOX_ON_SEGMENT)
    c = tr.contacts
    assert c is not None and c.position.shape[1] == 2
    rows = c.frame(len(tr.step) - 1)
    assert c.count[-1] == 2
    assert np.array_equal(c.normal[rows], [[0.0, 1.0], [0.0, 1.0]])
    assert sorted(np.round(c.position[rows, 0], 9)) == [-0.2, 0.8]
    weight = 1000.0 * G  # kg/m² × 1 m² × g
    assert abs(c.force[rows].sum() - weight) < 1e-9 * weight


def test_a_run_that_does_not_ask_records_nothing_and_the_same_frames() -> None:
    asked = rbsim.run(BOX_ON_PLANE)
    plain = rbsim.run(BOX_ON_PLANE.replace("output: {contacts: points}", ""))
    assert plain.contacts is None
    # recording reads the contact store and changes nothing in the run
    assert np.array_equal(asked.position, plain.position)
    assert np.array_equal(asked.orientation, plain.orientation)
    assert np.array_equal(asked.velocity, plain.velocity)


def recorded_push(tr) -> np.ndarray:  # noqa: ANN001 - a Trajectory
    """(T,N,D) N: the recorded normal forces on each of the trajectory's bodies, frame by
    frame (a point pushes its second body along its normal, its first the other way)."""
    c = tr.contacts
    assert c is not None
    n = tr.velocity.shape[1]
    push = np.zeros(tr.velocity.shape)
    for t in range(len(tr.step)):
        for r in range(c.frame(t).start, c.frame(t).stop):
            a, b = c.body[r]
            f = c.force[r] * c.normal[r]
            if b < n:
                push[t, b] += f
            if a < n:
                push[t, a] -= f
    return push


def unbalanced(tr) -> float:  # noqa: ANN001 - a Trajectory
    """The largest gap over the frames and dynamic bodies between a body's change of
    momentum less gravity over the step, m Δv / dt − m g, and the recorded normal forces on
    it, over its weight: 0 where they account for every push (a frictionless scene)."""
    dt = float(tr.time[1] - tr.time[0])
    m = np.asarray(tr.bodies.mass)
    d = tr.velocity.shape[2]
    g = np.array([0.0, -G, 0.0][:d])
    dynamic = np.isfinite(m) & (m > 0)
    m, push = m[dynamic], recorded_push(tr)[1:, dynamic]
    need = m[None, :, None] * (np.diff(tr.velocity[:, dynamic], axis=0) / dt - g)
    return float((np.linalg.norm(need - push, axis=2) / (m * G)[None, :]).max())


def frictionless(dimension: int, bodies: str, duration: float = 1.5, e: float = 0.0) -> str:
    """A frictionless scene recording its contact points: `bodies` on the ground."""
    ground = (
        "{plane: {normal: [0, 1, 0], offset: 0}}"
        if dimension == 3
        else "{segment: {a: [-5, 0], b: [5, 0]}}"
    )
    return f"""
version: 1
world: {{dimension: {dimension}, dt: 0.01, duration: {duration}}}
output: {{contacts: points}}
materials:
  m: {{density: 1000, friction: 0.0, restitution: {e}}}
bodies:
  - {{name: ground, type: static, material: m, shape: {ground}}}
{bodies}"""


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_bounce_records_the_mean_force_of_its_step(dimension: int) -> None:
    # the restitution stage's impulse is the point's force in the step of the impact:
    # its step's recorded force times dt is the ball's change of momentum (with gravity's)
    shape = "{sphere: {radius: 0.1}}" if dimension == 3 else "{circle: {radius: 0.1}}"
    at = vector(dimension, 0, 1, 0)
    ball = f"  - {{name: ball, position: {at}, material: m, shape: {shape}}}"
    tr = rbsim.run(frictionless(dimension, ball, e=0.5))
    i = tr.body("ball")
    vy = tr.velocity[:, i, 1]
    impacts = np.flatnonzero(np.diff(vy) > 1.0) + 1  # frames whose step turned the ball up
    assert len(impacts) >= 2
    push = recorded_push(tr)[:, i, 1]
    m = float(tr.bodies.mass[i])
    for t in impacts:
        assert push[t] > 0.0
        # (round-off of the momenta, m/s)
        assert abs(push[t] * 0.01 - m * (vy[t] - vy[t - 1] + G * 0.01)) < 1e-9 * m


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_heavy_box_on_a_light_plate_records_every_push(dimension: int) -> None:
    # the shock pass stops the 100 kg box on the 1 kg plate as if the plate were held
    # still: its pushes are the box's contact forces, and the plate's reaction goes on
    # into the ground's contacts, so every body's forces add up (round-off)
    plate = vector(dimension, 1, 0.1, 1)
    box = vector(dimension, 0.5, 0.5, 0.5)
    bodies = (
        f"  - {{name: plate, position: {vector(dimension, 0, 0.05, 0)}, material: m, mass: 1,"
        f" shape: {{box: {{size: {plate}}}}}}}\n"
        f"  - {{name: box, position: {vector(dimension, 0, 0.6, 0)},"
        f" velocity: {vector(dimension, 0, -2, 0)}, material: m, mass: 100,"
        f" shape: {{box: {{size: {box}}}}}}}\n"
    )
    for e in (0.0, 0.5):
        assert unbalanced(rbsim.run(frictionless(dimension, bodies, e=e))) < 1e-9


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_landing_stack_records_the_loads_that_hold_it(dimension: int) -> None:
    # five boxes dropped 1 cm onto each other: the shock pass takes their approaches as
    # they land and settle, and each box's recorded forces still account for its motion
    # (before the step's own impulses were recorded: 4.6 times a box's weight off). Up to
    # 1e-3 of a weight: the landing's normals are a hair off vertical (8e-4 measured in
    # 2D, 5e-5 in 3D), which moves the boxes sideways by a push not recorded as normal
    stack = "".join(
        f"  - {{name: b{i}, position: {vector(dimension, 0, 0.25 + 0.51 * i, 0)}, material: m,"
        f" shape: {{box: {{size: {vector(dimension, 0.5, 0.5, 0.5)}}}}}}}\n"
        for i in range(5)
    )
    tr = rbsim.run(frictionless(dimension, stack, duration=2.0))
    assert unbalanced(tr) < 1e-3
    # settled, the ground's points carry the whole stack's weight (up to 1e-3 of it: the
    # 2D stack still sways at 2 s, its momentum changing by 4.5e-4 of its weight a step)
    c = tr.contacts
    rows = c.frame(len(tr.step) - 1)
    on_ground = c.body[rows, 0] == tr.body("ground")
    weight = 5 * 250.0 * G if dimension == 2 else 5 * 125.0 * G
    assert abs(c.force[rows][on_ground].sum() - weight) < 1e-3 * weight


@pytest.mark.parametrize("dimension", [2, 3])
def test_recording_a_heavy_landing_changes_nothing_in_the_run(dimension: int) -> None:
    # the step impulses are read from the solver (in 2D handed back from its batches
    # each substep): the frames are those of a run that records nothing
    cube = vector(dimension, 0.5, 0.5, 0.5)
    stack = "".join(
        f"  - {{name: b{i}, position: {vector(dimension, 0.03 * i, 0.25 + 0.51 * i, 0)},"
        f" material: m, mass: {10 ** (i % 3)}, shape: {{box: {{size: {cube}}}}}}}\n"
        for i in range(5)
    )
    text = frictionless(dimension, stack).replace("friction: 0.0", "friction: 0.5")
    asked = rbsim.run(text)
    plain = rbsim.run(text.replace("output: {contacts: points}", ""))
    assert plain.contacts is None and asked.contacts is not None
    assert np.array_equal(asked.position, plain.position)
    assert np.array_equal(asked.velocity, plain.velocity)


def test_a_pile_grows_the_rows_and_keeps_every_point(tmp_path) -> None:
    out = pile(tmp_path, "pile", "output.contacts=points")
    tr = rbsim.load_trajectory(out)
    c = tr.contacts
    assert c is not None
    # more points per frame than the block and the file make room for at first: both grew
    assert c.count.max() > CONTACT_BLOCK_ROWS and c.count.max() > CONTACT_FILE_ROWS
    assert np.array_equal(c.count, tr.observables["contact_count"])
    assert np.array_equal(c.start, np.concatenate([[0], np.cumsum(c.count)[:-1]]))
    assert len(c.force) == c.count.sum()
    n = len(tr.bodies.name)
    assert c.body.min() >= 0 and c.body.max() < n and np.all(c.body[:, 0] != c.body[:, 1])
    assert np.allclose(np.linalg.norm(c.normal, axis=1), 1.0, atol=1e-12)  # unit normals
    assert np.all(c.force >= 0.0)  # a contact only pushes
    # every point lies on or above the ground (less the overlap a hard impact leaves,
    # a few cm at most: the pile's boxes are 0.5 m)
    assert c.position[:, 1].min() > -0.05
    # the ground's points have it first, pushing up
    on_ground = c.body[:, 0] == tr.body("ground")
    assert on_ground.any() and np.array_equal(
        c.normal[on_ground], np.tile([0.0, 1.0, 0.0], (int(on_ground.sum()), 1))
    )
    # the frames are those of a run that does not record contacts
    plain = rbsim.load_trajectory(pile(tmp_path, "plain"))
    assert np.array_equal(plain.position, tr.position)
    text = summarize(out)
    assert f"contacts   {c.count.sum()} points over {len(tr.step)} frames" in text
    assert f"at most {c.count.max()} in a frame" in text
    assert "contacts" not in summarize(tmp_path / "plain.h5").split("wall time")[0]


def test_bodies_left_out_are_named_by_their_rows_in_the_file(tmp_path) -> None:
    full = rbsim.load_trajectory(pile(tmp_path, "all", "output.contacts=points"))
    out = pile(
        tmp_path,
        "moving",
        "output.contacts=points",
        "output.bodies=moving",
        "output.precision=float32",
        "output.compression=gzip",
    )
    part = rbsim.load_trajectory(out)
    assert part.contacts is not None and full.contacts is not None
    assert np.array_equal(part.contacts.count, full.contacts.count)
    names = part.bodies.name + part.fixed.bodies.name  # the frames' bodies, then the static
    named = [[names[a], names[b]] for a, b in part.contacts.body]
    assert named == [[full.bodies.name[a], full.bodies.name[b]] for a, b in full.contacts.body]
    assert part.contacts.position.dtype == np.float32
    # float32 rounding of positions of a few metres (2^-24 relative)
    assert np.abs(part.contacts.position - full.contacts.position).max() < 1e-6


def test_an_interrupted_run_resumes_to_the_same_contacts(tmp_path) -> None:
    reference = rbsim.load_trajectory(pile(tmp_path, "ref", "output.contacts=points"))
    path = scenes_dir("3d") / "collapsing_pile.yaml"
    sets = ["world.duration=2", "output.contacts=points"]
    out = tmp_path / "stopped.h5"

    def stop(step: int, total: int) -> None:
        if step >= 60:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_scene(load_scene(path, sets), out, progress=stop, overrides=sets, flush_seconds=0)
    stopped = rbsim.load_trajectory(out)
    assert stopped.status == "interrupted" and 0 < len(stopped.step) < len(reference.step)
    resume_run(out)
    resumed = rbsim.load_trajectory(out)
    a, b = reference.contacts, resumed.contacts
    assert a is not None and b is not None
    for name in ("start", "count", "body", "position", "normal", "force"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_the_option_is_checked_like_any_key() -> None:
    with pytest.raises(rbsim.scene.SceneError, match="output.contacts"):
        load_scene_text(BOX_ON_PLANE.replace("contacts: points", "contacts: yes"), "<s>")


@pytest.mark.parametrize("compression", ["none", "gzip"])
def test_a_run_without_any_contact_records_an_empty_table(compression: str) -> None:
    ball = {
        "version": 1,
        "world": {"steps": 30},
        "output": {"contacts": "points", "compression": compression},
        "bodies": [{"shape": {"circle": {"radius": 1}}}],
    }
    c = rbsim.run(ball).contacts
    assert c is not None
    assert np.array_equal(c.count, np.zeros(31)) and np.array_equal(c.start, np.zeros(31))
    assert c.position.shape == (0, 2) and c.body.shape == (0, 2) and c.force.shape == (0,)


def test_a_large_pile_records_finite_forces() -> None:
    # 600 circles: the solver's regions regroup the shock pass's order by region, and the
    # loads handed down at the step's end must go by support level across the regions
    # (taken in the regrouped order, a body's supports were met before all its load had
    # come down, and shared over none of them: 560 forces of +inf from 2.47 s on)
    scene = {
        "version": 1,
        "world": {"dt": 1 / 60, "duration": 3},
        "solver": {"substeps": 1},
        "output": {"contacts": "points"},
        "materials": {"m": {"density": 1.0, "friction": 0.0, "restitution": 0.0}},
        "bodies": [
            {
                "name": "floor",
                "type": "static",
                "material": "m",
                "shape": {"segment": {"a": [-20, 0], "b": [20, 0]}},
            },
            {
                "name": "left",
                "type": "static",
                "material": "m",
                "shape": {"segment": {"a": [-20, 0], "b": [-20, 30]}},
            },
            {
                "name": "right",
                "type": "static",
                "material": "m",
                "shape": {"segment": {"a": [20, 0], "b": [20, 30]}},
            },
            {
                "grid": {
                    "name": "b",
                    "count": [40, 15],
                    "spacing": [0.9, 0.9],
                    "origin": [-17.5, 0.5],
                    "material": "m",
                    "shape": {"circle": {"radius": 0.4}},
                }
            },
        ],
    }
    c = rbsim.run(scene).contacts
    assert c is not None and len(c.force) > 50_000
    assert np.all(np.isfinite(c.force)) and np.all(c.force >= 0.0)
