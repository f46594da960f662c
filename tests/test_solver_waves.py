"""The solver's passes wave by wave (solver/waves.cpp, solve.cpp) give the result of the
sequential pass in solve order: manifolds of a wave share no dynamic body, so solving
them at once (four to a vector register) only swaps manifolds that do not interact. In 3D
the one-point manifolds go four at a time and the others one by one, wave by wave."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rbsim.core import CoreWorld
from rbsim.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENES = [
    "bench/scenes/pyramid20.yaml",  # two-point manifolds, block solve, friction
    "bench/scenes/circles1000.yaml",  # one-point manifolds
    "scenes/hard/card_house.yaml",  # thin boxes leaning: steep normals, mixed
    "scenes/hard/confined.yaml",  # an over-full box of circles: deep overlaps
    "scenes/hard/slab.yaml",  # mass ratio 400
    "scenes/stairs.yaml",  # boxes and balls down a staircase of static boxes
]
SCENES_3D = [  # (scene, steps before the passes)
    # spheres, capsules and pebbles on a pyramid of boxes struck by a ball, 0.5 s in: one-
    # point manifolds and faces of two to four points
    ("scenes/3d/collapsing_pile.yaml", 60),
    ("scenes/hard/confined_3d.yaml", 60),  # an over-full box of spheres: deep overlaps
    ("scenes/hard/pyramid5_3d.yaml", 60),  # boxes resting on boxes: four-point faces
    # a 100 t box landing on a pyramid, 4 steps in: waves that hold faces of three and of
    # four points (a wave's run of one count ends inside a batch)
    ("scenes/hard/heavy_top_3d.yaml", 4),
]
STATE = ("body_x", "body_q", "body_angle", "body_v", "body_w")


def _copy(src: CoreWorld, dst: CoreWorld) -> None:
    dst.engine.grow_store(src.contacts.key.shape[0], src.contacts.pairs.shape[0])
    s, d = src.engine.storage(), dst.engine.storage()
    for name, arr in s.items():
        if name != "grid":
            d[name][...] = arr
    for name in STATE:
        getattr(dst.engine, name)[...] = getattr(src.engine, name)


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("use_bias", [True, False], ids=["solve", "relax"])
def test_a_pass_wave_by_wave_equals_the_pass_in_solve_order(name, use_bias):
    scene = load_scene(ROOT / name)
    seq = CoreWorld.from_scene(scene)
    seq.advance(120)
    waves = CoreWorld.from_scene(scene)
    _copy(seq, waves)
    waves.stage("find_waves")
    h = seq.config.dt / seq.config.substeps
    args = dict(inv_h=1.0 / h, use_bias=use_bias, shift=0.0 if use_bias else h, threshold=1.0)
    n = int(seq.contacts.count[0])
    assert n > 0
    assert int(waves.contacts.wave_count) <= n
    for _ in range(3):  # repeated passes: the impulses accumulate
        for w in (seq, waves):  # the lists of one pass (a step empties them per substep)
            w.contacts.count[5] = w.contacts.count[6] = 0
        seq.stage("solve_contacts", order="solve_order", n=n, **args)
        waves.stage("solve_waves", **args)
        _same_lists(seq, waves)
    # 1e-12 (m/s, N·s): the vector code rounds some sums in another order
    for name_ in ("body_v", "body_w"):
        a, b = getattr(seq.state, name_), getattr(waves.state, name_)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    for field in ("normal_impulse", "tangent_impulse", "max_normal_impulse"):
        a, b = getattr(seq.contacts, field)[:n], getattr(waves.contacts, field)[:n]
        points = seq.contacts.points[:n]
        for k in (0, 1):
            on = points > k
            np.testing.assert_allclose(b[on, k], a[on, k], rtol=0, atol=1e-12)


@pytest.mark.parametrize(("name", "steps"), SCENES_3D)
@pytest.mark.parametrize("use_bias", [True, False], ids=["solve", "relax"])
def test_a_3d_pass_wave_by_wave_equals_the_pass_in_solve_order(name, steps, use_bias):
    # two worlds stepped alike (the 3D rows are not among the storage's views to copy):
    # the same bits, then one pass each way
    scene = load_scene(ROOT / name)
    seq, waves = CoreWorld.from_scene(scene), CoreWorld.from_scene(scene)
    seq.advance(steps)
    waves.advance(steps)
    assert np.array_equal(seq.state.body_v, waves.state.body_v)
    waves.stage("find_waves")
    c = waves.contacts
    n = int(seq.contacts.count[0])
    # one-point manifolds in lanes, and faces of more points
    assert int(c.wave_batch[int(c.wave_count)]) > 0 or "pyramid" in name or "heavy" in name
    assert int(c.wave_single_batch[int(c.wave_count)]) > 0 or "confined" in name
    h = seq.config.dt / seq.config.substeps
    args = dict(inv_h=1.0 / h, use_bias=use_bias, shift=0.0 if use_bias else h, threshold=1.0)
    for _ in range(3):
        for w in (seq, waves):
            w.contacts.count[5] = w.contacts.count[6] = 0
        seq.stage("solve_contacts", order="solve_order", n=n, **args)
        waves.stage("solve_waves", **args)
        _same_lists(seq, waves)
    assert np.abs(seq.state.body_v).max() > 0.0
    # round-off, amplified by the faces' rigid blocks: four coplanar points make a block of
    # rank 3, regularised by BLOCK_EPS (1e-9) of its diagonal, so a last-bit difference (the
    # compiler fuses the vector code's products and sums differently; built without fused
    # multiply-adds the two agree to the bit) can move the impulses by up to 1e-16 / 1e-9
    # of the largest one: 1e-7 of each array's largest value
    for name_ in ("body_v", "body_w", "body_l"):
        a, b = getattr(seq.state, name_), getattr(waves.state, name_)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-7 * np.abs(a).max() + 1e-15)
    for field in ("normal_impulse", "tangent_impulse", "max_normal_impulse"):
        a, b = getattr(seq.contacts, field)[:n], getattr(waves.contacts, field)[:n]
        points = seq.contacts.points[:n]
        for k in range(4):
            on = points > k
            np.testing.assert_allclose(
                b[on, k], a[on, k], rtol=0, atol=1e-7 * np.abs(a).max() + 1e-15
            )


def _same_lists(seq: CoreWorld, waves: CoreWorld) -> None:
    """The restitution stage's and the deep overlaps' lists name the same manifolds (in
    another order: wave by wave)."""
    for count, arr in ((5, "bounce_list"), (6, "relax_list")):
        ka, kb = int(seq.contacts.count[count]), int(waves.contacts.count[count])
        assert ka == kb
        la = sorted(getattr(seq.contacts, arr)[:ka].tolist())
        lb = sorted(getattr(waves.contacts, arr)[:kb].tolist())
        assert la == lb


def test_waves_put_no_two_manifolds_of_one_dynamic_body_together():
    w = CoreWorld.from_scene(load_scene(ROOT / "bench/scenes/pyramid20.yaml"))
    w.advance(30)
    c = w.contacts
    dynamic = w.model.body_type == 0
    for g in range(int(c.wave_count)):
        ms = c.wave_order[c.wave_start[g] : c.wave_start[g + 1]]
        bodies = [b for m in ms for b in (c.body_a[m], c.body_b[m]) if dynamic[b]]
        assert len(bodies) == len(set(bodies))


@pytest.mark.parametrize("name", [s for s in SCENES if "stairs" not in s])  # (in flight)
def test_warm_start_wave_by_wave_equals_the_warm_start_in_manifold_order(name):
    scene = load_scene(ROOT / name)
    seq = CoreWorld.from_scene(scene)
    seq.advance(120)
    waves = CoreWorld.from_scene(scene)
    _copy(seq, waves)
    waves.stage("find_waves")
    assert int(seq.contacts.count[0]) > 0
    before = seq.state.body_v.copy()
    seq.stage("warm_start")
    waves.stage("warm_start_waves")
    assert not np.array_equal(seq.state.body_v, before)  # it has impulses to apply
    # 1e-12 m/s and rad/s: a body's impulses are summed in another order
    np.testing.assert_allclose(waves.state.body_v, seq.state.body_v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(waves.state.body_w, seq.state.body_w, rtol=0, atol=1e-12)


def _holds(c, m: int) -> bool:
    k = int(c.points[m])
    return bool(np.any(c.normal_impulse[m, :k] != 0) or np.any(c.tangent_impulse[m, :k] != 0))


def test_batches_fill_their_lanes_across_waves():
    # a manifold goes into the first batch of its point count with room after the last
    # batch of the manifolds before it on its bodies, not only into its own wave's: a
    # pyramid's waves hold 4 or 5 manifolds, and packed wave by wave three lanes in four
    # were used (0.77 of pyramid-20's, 0.84 of the circles'). Each batch is a wave of its
    # own, of one point count, its manifolds sharing no dynamic body
    for name, steps, fill in (
        ("bench/scenes/pyramid20.yaml", 120, 0.85),
        ("bench/scenes/circles1000.yaml", 300, 0.9),
    ):
        w = CoreWorld.from_scene(load_scene(ROOT / name))
        w.advance(steps)
        c = w.contacts
        c.count[7] = 0  # graph_unchanged: the waves packed anew, not kept from the last step
        n = int(c.count[0])
        w.stage("find_waves")
        batches = int(c.wave_count)
        assert int(c.wave_start[batches]) == n  # every manifold, once
        for g in range(batches):
            members = c.wave_order[c.wave_start[g] : c.wave_start[g + 1]]
            assert 1 <= len(members) <= 4
            assert len({int(c.points[m]) for m in members}) == 1
        assert n / (4 * batches) >= fill, (name, n / (4 * batches))


def test_3d_faces_that_hold_an_impulse_go_into_lanes_four_points_too():
    # each wave is one unit: one-point manifolds (before wave_single), or faces of one point
    # count that hold an impulse (wave_single to wave_idle, in a batch of faces3), or faces
    # that hold none (from wave_idle, solved one at a time), up to four, sharing no dynamic
    # body; the faces of four points that hold one are packed four to a batch
    # (solve_face_3d<4>), not left one at a time, and across waves: the units of a 5-layer
    # pyramid's faces fill 0.70 of their lanes (wave by wave 0.645, 35 of 69 batches of
    # fewer than three faces left one at a time)
    w = CoreWorld.from_scene(load_scene(ROOT / "scenes/hard/pyramid5_3d.yaml"))
    w.advance(60)
    w.stage("find_waves")
    c = w.contacts
    dynamic = w.model.body_type == 0
    n_held = n_idle = 0
    for g in range(int(c.wave_count)):
        members = [int(m) for m in c.wave_order[c.wave_start[g] : c.wave_start[g + 1]]]
        held = [int(m) for m in c.wave_order[c.wave_single[g] : c.wave_idle[g]]]
        idle = [int(m) for m in c.wave_order[c.wave_idle[g] : c.wave_start[g + 1]]]
        assert 1 <= len(members) <= 4 and (not held or not idle)
        assert all(_holds(c, m) for m in held) and not any(_holds(c, m) for m in idle)
        assert len({int(c.points[m]) for m in held}) <= 1
        assert min((int(c.points[m]) for m in held + idle), default=2) >= 2
        bodies = [b for m in members for b in (c.body_a[m], c.body_b[m]) if dynamic[b]]
        assert len(bodies) == len(set(bodies))
        n_held, n_idle = n_held + len(held), n_idle + len(idle)
    assert n_held and n_idle  # both kinds present
    faces = int(c.wave_single_batch[int(c.wave_count)])
    assert 4 in c.face_batch_points[:faces]
    assert n_held / (4 * faces) >= 0.68


def test_a_manifold_packed_idle_that_holds_an_impulse_is_solved():
    # manifolds packed among those that held nothing, given an impulse after the waves
    # were packed: their batches are no longer idle, and the pass solves them as the pass
    # in solve order does
    scene = load_scene(ROOT / "bench/scenes/pyramid20.yaml")
    seq = CoreWorld.from_scene(scene)
    seq.advance(120)
    waves = CoreWorld.from_scene(scene)
    _copy(seq, waves)
    waves.stage("find_waves")
    c = waves.contacts
    idle = [
        int(m)
        for g in range(int(c.wave_count))
        for m in c.wave_order[c.wave_start[g] : c.wave_single[g]]
        if not _holds(c, int(m))
    ]
    picked = idle[:: max(1, len(idle) // 8)]
    assert picked
    for w in (seq, waves):
        for m in picked:
            w.contacts.normal_impulse[m, :2] = 0.5  # N·s: more than a box's weight holds
    h = seq.config.dt / seq.config.substeps
    args = dict(inv_h=1.0 / h, use_bias=True, shift=0.0, threshold=1.0)
    seq.stage("solve_contacts", order="solve_order", n=int(c.count[0]), **args)
    waves.stage("solve_waves", **args)
    a, b = seq.contacts.normal_impulse[picked], waves.contacts.normal_impulse[picked]
    assert not np.any(a == 0.5)  # solved: the impulse held was not what the contact asks
    # 1e-12 (m/s, N·s): the vector code rounds some sums in another order
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    for name_ in ("body_v", "body_w"):
        np.testing.assert_allclose(
            getattr(waves.state, name_), getattr(seq.state, name_), rtol=0, atol=1e-12
        )
