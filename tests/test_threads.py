"""solver.threads: the step on several threads gives the same state, bit for bit, as on
one (Box2D's determinism promise). The solver's passes run region by region
(cpp/src/solver/regions.cpp), with regions fixed by the state and never by the thread
count; the other parallel stages split independent items. Each scene is stepped on 1, 2
and 3 threads and the state hashed."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from rbsim import config
from rbsim.config import make_config
from rbsim.core import THREADS_MAX, CoreWorld
from rbsim.scene import SceneError, load_scene, load_scene_text, schema
from rbsim.scene.compile import build

ROOT = Path(__file__).resolve().parents[1]

# 576 spheres in a 12 x 4 x 12 block, touching, settling onto a plane: 3D with regions;
# and a crate beside them, so that the threads' parts of the 578 bodies start at indices
# that do not divide by 4 (the position update moves bodies four at a time)
SPHERES_3D = """
version: 1
name: spheres
world: {dimension: 3, dt: 1/120, steps: 10}
materials:
  ball: {density: 1000, friction: 0.5, restitution: 0.0}
bodies:
  - {name: ground, type: static, material: ball, shape: {plane: {normal: [0, 1, 0], offset: 0}}}
  - grid:
      count: [12, 4, 12]
      spacing: [0.5, 0.5, 0.5]
      origin: [-2.75, 0.26, -2.75]
      material: ball
      shape: {sphere: {radius: 0.25}}
  - {name: crate, position: [4, 0.25, 0], material: ball, shape: {box: {size: [0.5, 0.5, 0.5]}}}
"""


CIRCLES_PADDLE = (
    (ROOT / "bench/scenes/circles1000.yaml").read_text()
    + """
  - name: paddle
    type: kinematic
    position: [-9, 1]
    velocity: [2, 0]
    angular_velocity: 0.5
    shape: {box: {size: [0.5, 2]}}
    material: ball
"""
)


def _world(scene, threads: int) -> CoreWorld:  # noqa: ANN001 - a Scene
    # every step on `threads` threads (a scene without solver.threads would have the step
    # choose, and its steps before the first trial run on one)
    model, state = build(scene)
    cfg = make_config(scene)._replace(threads=threads, choose_threads=False)
    return CoreWorld.from_arrays(model, state, cfg, scene.world.dimension, scene)


def _digest(world: CoreWorld) -> str:
    s = world.state
    h = hashlib.sha256()
    for a in (s.body_x, s.body_q, s.body_v, s.body_w, s.body_l):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


CASES = {
    # a settling pyramid of 820 boxes (two-point manifolds, the shock pass), from rest
    "pyramid40": (lambda: load_scene(ROOT / "bench/scenes/pyramid40.yaml"), 40),
    # 1000 circles falling into a box (one-point manifolds, bounces, time of impact)
    "circles1000": (lambda: load_scene(ROOT / "bench/scenes/circles1000.yaml"), 100),
    "spheres3d": (lambda: load_scene_text(SPHERES_3D), 10),
    # the circles with a turning kinematic paddle driven through them: a body of neither
    # region whose velocity both regions' passes read (each region's copy of the
    # velocities takes it once a step) and whose motion the first region's thread makes
    "circles_paddle": (lambda: load_scene_text(CIRCLES_PADDLE), 60),
}


@pytest.mark.parametrize("name", list(CASES))
def test_every_thread_count_gives_the_same_bits(name):
    make, steps = CASES[name]
    scene = make()
    digests = []
    for threads in (1, 2, 3):
        world = _world(scene, threads)
        assert world.engine.threads == threads
        world.advance(steps)
        assert world.contact_count > 0
        digests.append(_digest(world))
        # the scene is split: the threads have regions to share (else the test shows
        # only the exact serial path)
        storage = world.engine.storage()
        assert int(storage["region_count"]) == 2
    assert digests[1] == digests[0]
    assert digests[2] == digests[0]


def test_a_run_that_chooses_its_threads_gives_the_same_bits():
    # solver.threads not set: each step runs on one thread or on all, whichever the run's
    # trials timed faster, a trial alternating the two; the state must not move by a bit
    scene = load_scene(ROOT / "bench/scenes/circles1000.yaml")
    model, state = build(scene)
    cfg = make_config(scene)._replace(threads=2, choose_threads=True)
    chooser = CoreWorld.from_arrays(model, state, cfg, scene.world.dimension, scene)
    steps = 0
    # (the first trial begins after 0.05 s of stepping: its time, not a step count)
    while chooser.engine.thread_trials < 2 and steps < 20000:
        chooser.advance(10)
        steps += 10
    assert chooser.engine.thread_trials >= 2
    assert chooser.engine.threads_chosen in (1, 2)
    one = _world(scene, 1)
    one.advance(steps)
    assert one.engine.thread_trials == 0 and one.engine.threads_chosen == 1
    assert _digest(chooser) == _digest(one)


def test_regions_are_strips_across_gravity_with_few_joining_manifolds():
    scene = load_scene(ROOT / "bench/scenes/pyramid40.yaml")
    world = _world(scene, 1)
    world.advance(5)
    st = world.engine.storage()
    region = st["body_region"][: len(scene.bodies)]
    x = world.state.body_x[:, 0]
    dynamic = region >= 0
    assert region[0] == -1  # the static ground
    # equal counts, and the left strip left of the right one (split along x, not y)
    assert abs(int((region == 0).sum()) - int((region == 1).sum())) <= 1
    # (1 mm: the strips were cut at the last change of the contact graph, and the boxes
    # at the middle, a column of them at x = 0, have settled by micrometres since)
    assert x[region == 0].max() <= x[region == 1].min() + 1e-3
    assert x[region == 0].min() < -15 and x[region == 1].max() > 15
    bounds = st["segment_order"]
    n = int(world.contacts.count[0])
    assert bounds[0] == 0 and bounds[3] == n  # two regions, their cut, nothing else
    joints = int(bounds[3] - bounds[2])
    # the cut down the middle joins about two manifolds per row of 40: a few percent
    assert 0 < joints < 0.05 * n
    assert dynamic.sum() == 820


def test_the_profile_clocks_the_region_tasks_alone_and_side_by_side():
    # (World.region_task_seconds, bench/threads.py's "tasks" column) one thread runs the
    # two regions' tasks one after the other, two threads side by side; without the
    # profile nothing is clocked
    scene = load_scene(ROOT / "bench/scenes/pyramid40.yaml")
    clocked = {}
    for threads in (1, 2):
        world = _world(scene, threads)
        world.advance(2)
        assert world.engine.region_task_seconds == {"alone": (0.0, 0), "paired": (0.0, 0)}
        world.engine.profile = True
        world.advance(3)
        clocked[threads] = world.engine.region_task_seconds
    # each substep's warm start, solve, relax and shock pass: 4 passes of 4 substeps a step
    alone_s, alone_n = clocked[1]["alone"]
    assert alone_n >= 3 * 4 * 4 and alone_s > 0.0
    assert clocked[1]["paired"] == (0.0, 0)
    paired_s, paired_n = clocked[2]["paired"]
    assert paired_n == alone_n and paired_s > 0.0
    assert clocked[2]["alone"] == (0.0, 0)


def test_a_small_scene_is_one_region_and_keeps_the_sequential_order():
    scene = load_scene(ROOT / "bench/scenes/pyramid20.yaml")  # 210 boxes
    world = _world(scene, 2)
    world.advance(5)
    st = world.engine.storage()
    assert int(st["region_count"]) == 1
    n = int(world.contacts.count[0])
    assert list(st["segment_order"][:3]) == [0, n, n]


def _message(text: str) -> str:
    with pytest.raises(SceneError) as info:
        load_scene_text(text, "test.yaml")
    return str(info.value)


BODY = "bodies:\n  - {shape: {circle: {radius: 1}}}\n"
BASE = "version: 1\nworld: {dt: 0.01, steps: 1}\nsolver:\n  threads: %s\n" + BODY


@pytest.mark.parametrize("value", ["0", "65", "1.5", "many"])
def test_solver_threads_is_validated_with_its_place(value):
    message = _message(BASE % value)
    assert "test.yaml:4:12: solver.threads" in message


def test_threads_default_to_the_cores_and_to_one_in_workers():
    scene = load_scene_text(BASE % "3")
    assert make_config(scene).threads == 3
    plain = load_scene_text("version: 1\nworld: {dt: 0.01, steps: 1}\n" + BODY)
    assert plain.solver.threads is None
    assert make_config(plain).threads == min(config.available_cores(), 64)
    # without the key the step chooses between one thread and the cores as it runs
    assert make_config(plain).choose_threads and not make_config(scene).choose_threads
    with config.threads_default(1):  # rbsim batch and sweep workers
        assert make_config(plain).threads == 1
        assert make_config(scene).threads == 3  # the scene's own wins
        assert not make_config(plain).choose_threads
    assert make_config(plain).threads == min(config.available_cores(), 64)


def test_the_schema_bound_is_the_engines():
    assert schema.THREADS_MAX == THREADS_MAX == 64
    model, state = build(load_scene_text(BASE % "2"))
    cfg = make_config(load_scene_text(BASE % "2"))
    for bad in (0, THREADS_MAX + 1):  # the engine checks what crosses the binding too
        with pytest.raises(ValueError, match="threads must be between 1 and 64"):
            CoreWorld.from_arrays(model, state, cfg._replace(threads=bad), 2)
