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
