// solver/warm_start.cpp: last substep's impulses applied again, as the impulse and moment
// they are, equal and opposite on the two bodies.
#include <cmath>

#include "check.hpp"
#include "contacts3d_builder.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

// Impulses set at a box-on-box face: each body's velocity changes by ±P/m and its spin by
// ±Σ (r × p)/I, with P = Σ (λn n + λt t); the total momentum is unchanged.
TEST(warm_start_applies_stored_impulses_equal_and_opposite) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.box({0.0, 0.0}, 1.0, 0.5, 4.0);
  s.box({0.3, 0.75}, 0.25, 0.25, 1.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  auto& c = w.contacts;
  CHECK(c.count.manifolds == 1 && c.points[0] == 2);
  c.normal_impulse[0] = {0.3, 0.1};
  c.tangent_impulse[0] = {-0.05, 0.02};
  const int a = c.body_a[0], b = c.body_b[0];
  const Vec2 n = c.normal[0], t{n.y, -n.x};
  Vec2 p{};
  double la = 0.0, lb = 0.0;  // N·m·s
  for (int k = 0; k < 2; ++k) {
    const Vec2 pk = c.normal_impulse[0][k] * n + c.tangent_impulse[0][k] * t;
    p += pk;
    la += cross(c.anchor_a[0][k], pk);
    lb += cross(c.anchor_b[0][k], pk);
  }
  warm_start(w.model, w.state, c);
  const auto& m = w.model;
  CHECK_NEAR(w.state.body_v[a].x, m.body_inv_mass[a] * p.x, 1e-15);
  CHECK_NEAR(w.state.body_v[a].y, m.body_inv_mass[a] * p.y, 1e-15);
  CHECK_NEAR(w.state.body_v[b].y, -m.body_inv_mass[b] * p.y, 1e-15);
  CHECK_NEAR(w.state.body_w[a], m.body_inv_inertia[a] * la, 1e-15);
  CHECK_NEAR(w.state.body_w[b], -m.body_inv_inertia[b] * lb, 1e-15);
  const Vec2 total = m.body_mass[0] * w.state.body_v[0] + m.body_mass[1] * w.state.body_v[1];
  CHECK_NEAR(total.x, 0.0, 1e-15);
  CHECK_NEAR(total.y, 0.0, 1e-15);
}

// Against the ground only the box moves; the static body's state is not written.
TEST(warm_start_leaves_static_body_alone) {
  SceneBuilder s;
  const int g = s.ground();
  const int box = s.box({0.0, 0.5}, 0.5, 0.5, 2.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  w.contacts.normal_impulse[0] = {0.5, 0.5};
  warm_start(w.model, w.state, w.contacts);
  CHECK_NEAR(w.state.body_v[box].y, 0.5, 1e-15);  // (0.5 + 0.5) N·s / 2 kg
  CHECK_NEAR(w.state.body_w[box], 0.0, 1e-15);    // mirror-image impulses: no spin
  CHECK(w.state.body_v[g].x == 0.0 && w.state.body_v[g].y == 0.0 && w.state.body_w[g] == 0.0);
}

// 2D: the batches take their manifolds' impulses (take_impulses) and the step's passes
// read and write them there; give_impulses writes back what they hold. Taken and given
// back untouched, the store is unchanged to the bit; while the batches hold them, the
// store's copy is not what a pass reads; the passes on the batches' impulses, given back,
// are the passes one manifold at a time on the store's (a wave's manifolds share no
// dynamic body, so the two orders agree, to the rounding of the multiply-adds that the
// compiler fuses in the solver's files, -ffp-contract=fast, not always alike in the lanes'
// code and in the one-at-a-time code).
TEST(batches_hold_the_impulses_between_take_and_give) {
  auto scene = [](SceneBuilder& s) -> World<2>& {
    s.world.model.gravity = {0.0, -10.0};
    s.ground();
    s.box({-2.0, 0.49}, 0.5, 0.5, 2.0);           // two points on the ground
    s.box({-2.0, 1.48}, 0.5, 0.5, 1.0);           // and on the box
    s.circle({1.0, 0.245}, 0.25, 1.0);            // one point
    s.circle({1.5, 0.245}, 0.25, 1.0, {}, {-0.3, 0.0});  // and one between the two balls
    return s.finish();
  };
  SceneBuilder s0, s1;
  World<2>& lanes = scene(s0);
  World<2>& one = scene(s1);
  for (World<2>* w : {&lanes, &one}) {
    rbsim::test::collide(*w);
    auto& c = w->contacts;
    for (std::int64_t m = 0; m < c.count.manifolds; ++m) {  // N·s: some held, some not
      c.normal_impulse[m] = {0.02 * static_cast<double>(m), 0.01};
      c.tangent_impulse[m] = {0.003 * static_cast<double>(m % 2), -0.001};
    }
  }
  auto& c = lanes.contacts;
  CHECK(c.count.manifolds == 5);
  find_waves(lanes.model, c);
  const auto before_n = c.normal_impulse;
  const auto before_t = c.tangent_impulse;
  take_impulses(c);
  CHECK(c.impulses_in_lanes);
  give_impulses(c);
  CHECK(!c.impulses_in_lanes);
  for (std::int64_t m = 0; m < c.count.manifolds; ++m) {
    for (int k = 0; k < c.points[m]; ++k) {
      CHECK(c.normal_impulse[m][k] == before_n[m][k]);
      CHECK(c.tangent_impulse[m][k] == before_t[m][k]);
    }
  }
  // one manifold's row changed in the store while the batches hold the impulses (as the
  // restitution stage changes those it lists): taken alone, it is what is given back
  take_impulses(c);
  const std::int32_t pick[] = {3};
  c.normal_impulse[3][0] = 0.75;
  c.normal_impulse[1][0] = 9.0;  // (not taken: the batches' value is given back)
  take_impulses(c, pick, 1);
  give_impulses(c);
  CHECK(c.normal_impulse[3][0] == 0.75 && c.normal_impulse[1][0] == before_n[1][0]);
  // and given alone, only its row is written
  take_impulses(c);
  c.normal_impulse[1][0] = 9.0;
  c.normal_impulse[3][0] = 8.0;
  give_impulses(c, pick, 1);
  CHECK(c.normal_impulse[3][0] == 0.75 && c.normal_impulse[1][0] == 9.0);
  give_impulses(c);
  c.normal_impulse[3] = before_n[3];
  // a list of more than half the manifolds is given as all of them: the batches no longer
  // hold the impulses (the next pass takes them all), and the store has every one
  take_impulses(c);
  const std::int32_t most[] = {0, 1, 2};
  c.normal_impulse[4][0] = 9.0;
  give_impulses(c, most, 3);
  CHECK(!c.impulses_in_lanes && c.normal_impulse[4][0] == before_n[4][0]);
  // while taken, the store's copy is not read: scribbled over, the pass is the same
  const double inv_h = 1.0 / rbsim::test::substep(lanes);
  take_impulses(c);
  for (auto& lam : c.normal_impulse) lam = {7.0, 7.0};
  for (auto& lam : c.tangent_impulse) lam = {-7.0, -7.0};
  warm_start_range(lanes.model, lanes.state, c, 0, c.wave_count);
  PassLog log = PassLog::direct(c);
  solve_wave_range(lanes.model, lanes.state, c, inv_h, true, 0.0, 1.0, 0, c.wave_count, log);
  solve_wave_range(lanes.model, lanes.state, c, inv_h, false, 0.0, 1.0, 0, c.wave_count, log);
  give_impulses(c);
  // the same passes one manifold at a time, in solve order, on the store's impulses
  auto& o = one.contacts;
  warm_start(one.model, one.state, o);
  solve_contacts(one.model, one.state, o, inv_h, true, 0.0, 1.0, o.solve_order.data(),
                 o.count.manifolds);
  solve_contacts(one.model, one.state, o, inv_h, false, 0.0, 1.0, o.solve_order.data(),
                 o.count.manifolds);
  // (tolerances: the rounding of a few fused operations on impulses of 0.1 N·s and
  // velocities of 1 m/s; a lane solved otherwise differs by far more)
  for (std::size_t i = 0; i < lanes.state.body_v.size(); ++i) {
    CHECK_NEAR(lanes.state.body_v[i].x, one.state.body_v[i].x, 1e-15);
    CHECK_NEAR(lanes.state.body_v[i].y, one.state.body_v[i].y, 1e-15);
    CHECK_NEAR(lanes.state.body_w[i], one.state.body_w[i], 1e-15);
  }
  for (std::int64_t m = 0; m < c.count.manifolds; ++m) {
    for (int k = 0; k < c.points[m]; ++k) {
      CHECK_NEAR(c.normal_impulse[m][k], o.normal_impulse[m][k], 1e-16);
      CHECK_NEAR(c.tangent_impulse[m][k], o.tangent_impulse[m][k], 1e-16);
      CHECK_NEAR(c.max_normal_impulse[m][k], o.max_normal_impulse[m][k], 1e-16);
      CHECK_NEAR(c.approach_velocity[m][k], o.approach_velocity[m][k], 1e-15);
    }
  }
}

// 3D warm start: each point's stored normal and friction impulses are applied again, as
// momentum: Δv = Σ p / m and ΔL = Σ r × p on each body (ω from L), with the part of a
// stored friction impulse along this step's normal dropped.
TEST(warm_start_3d_applies_stored_impulses) {
  using rbsim::test::about;
  rbsim::test::Builder3 s;
  const Sym3 ia{0.30, 0.45, 0.60, 0.05, -0.03, 0.02};
  const Sym3 ib{0.80, 0.50, 0.70, -0.04, 0.06, 0.01};
  const int a = s.body({0.0, 1.0, 0.0}, 2.0, ia, about({1, 2, 3}, 0.7), {0.1, 0.2, 0.3});
  const int b = s.body({0.1, 0.0, 0.2}, 3.0, ib, about({0, 1, 1}, 0.4));
  World<3>& w = s.finish();
  const Vec3 n{0, 1, 0};
  const std::vector<Vec3> p{{0.3, 0.5, 0.2}, {-0.2, 0.5, 0.1}};
  s.manifold(a, b, n, p, 0.5, 0.0);
  s.prepare();
  auto& c = w.contacts;
  c.normal_impulse[0][0] = 0.7;
  c.normal_impulse[0][1] = 0.4;
  c.tangent_impulse[0][0] = {0.1, 0.05, -0.2};  // its y part is no friction: dropped
  c.tangent_impulse[0][1] = {-0.05, 0.0, 0.03};
  const State<3> before = w.state;
  warm_start(w.model, w.state, c);
  Vec3 total{}, la{}, lb{};
  for (int k = 0; k < 2; ++k) {
    const Vec3 jt = c.tangent_impulse[0][k];
    const Vec3 pk = c.normal_impulse[0][k] * n + Vec3{jt.x, 0.0, jt.z};
    total += pk;
    la += cross(p[k] - before.body_x[a], pk);
    lb += cross(p[k] - before.body_x[b], pk);
  }
  // round-off of momenta below 1 N·s
  CHECK_NEAR(length(w.state.body_v[a] - before.body_v[a] - 0.5 * total), 0.0, 1e-15);
  CHECK_NEAR(length(w.state.body_v[b] - before.body_v[b] + (1.0 / 3.0) * total), 0.0, 1e-15);
  CHECK_NEAR(length(w.state.body_l[a] - before.body_l[a] - la), 0.0, 1e-15);
  CHECK_NEAR(length(w.state.body_l[b] - before.body_l[b] + lb), 0.0, 1e-15);
  const Vec3 wa = rbsim::test::world_apply(w.state.body_q[a], w.model.body_inv_inertia[a],
                                           w.state.body_l[a]);
  CHECK_NEAR(length(w.state.body_w[a] - wa), 0.0, 1e-14);
}

// A 3D manifold that holds no impulse (a speculative contact) has none to apply: its
// bodies are left as they are, bit for bit, their ω too.
TEST(warm_start_3d_skips_a_manifold_that_holds_nothing) {
  using rbsim::test::about;
  rbsim::test::Builder3 s;
  const Sym3 ia{0.30, 0.45, 0.60, 0.05, -0.03, 0.02};
  const int a = s.body({0.0, 1.0, 0.0}, 2.0, ia, about({1, 2, 3}, 0.7), {0.1, 0.2, 0.3},
                       {0.3, -0.2, 0.5});
  const int g = s.fixed({0, 0, 0});
  World<3>& w = s.finish();
  s.manifold(a, g, {0, 1, 0}, {{0.3, 0.5, 0.2}}, 0.5, 0.0, 0.01);
  s.prepare();
  w.state.body_w[a] = {0.31, -0.2, 0.5};  // rad/s: not the ω of its L, which a warm start sets
  const State<3> before = w.state;
  warm_start(w.model, w.state, w.contacts);
  CHECK(w.state.body_v[a].x == before.body_v[a].x && w.state.body_v[a].y == before.body_v[a].y &&
        w.state.body_v[a].z == before.body_v[a].z);
  CHECK(length(w.state.body_l[a] - before.body_l[a]) == 0.0);
  CHECK(length(w.state.body_w[a] - before.body_w[a]) == 0.0);
  w.contacts.normal_impulse[0][0] = 1e-3;  // N·s: now it holds one, applied
  warm_start(w.model, w.state, w.contacts);
  CHECK(w.state.body_v[a].y > before.body_v[a].y);
}

RBSIM_TEST_MAIN
