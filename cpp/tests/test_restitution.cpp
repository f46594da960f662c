// solver/restitution.cpp: bounces by the restitution hypothesis, v_n⁺ = −e v_n⁻, through
// whole steps of worlds without gravity.
#include <algorithm>
#include <cmath>

#include "check.hpp"
#include "contacts3d_builder.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::Material;
using rbsim::test::SceneBuilder;

// Two balls, 1 kg at +3 m/s and 2 kg at −1 m/s, 1 cm apart: after the impact (within the
// first step) v1' = (m1 v1 + m2 v2 − m2 e (v1 − v2)) / (m1 + m2), and v2' likewise, to
// round-off, for e = 1 and e = 0.5.
TEST(isolated_collision_matches_restitution_formula) {
  for (const double e : {1.0, 0.5}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    const Material mat{0.0, e};
    const int b1 = s.circle({-0.255, 0.0}, 0.25, 1.0, mat, {3.0, 0.0});
    const int b2 = s.circle({0.255, 0.0}, 0.25, 2.0, mat, {-1.0, 0.0});
    World<2>& w = s.finish();
    for (int k = 0; k < 10; ++k) CHECK(w.step());
    const double m1 = 1.0, m2 = 2.0, v1 = 3.0, v2 = -1.0;
    const double p = m1 * v1 + m2 * v2;
    CHECK_NEAR(w.state.body_v[b1].x, (p - m2 * e * (v1 - v2)) / (m1 + m2), 1e-12);
    CHECK_NEAR(w.state.body_v[b2].x, (p + m1 * e * (v1 - v2)) / (m1 + m2), 1e-12);
    CHECK(w.state.body_v[b1].y == 0.0 && w.state.body_v[b2].y == 0.0);
  }
}

// Newton's cradle: a ball strikes a touching row of four equal balls (e = 1) 1 cm away at
// 2 m/s, within the first step: the struck end passes the momentum along the row and the
// far ball leaves with the striker's speed, all within that step. Struck from the left by
// the first shape the impacts run in the manifolds' order; struck from the right by the
// last shape against it, so the row is resolved over several passes of the restitution
// stage within one substep.
TEST(newtons_cradle_row_passes_its_momentum_on) {
  for (const bool from_left : {true, false}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    const Material steel{0.0, 1.0};
    const double r = 0.1;
    if (from_left) s.circle({-0.21, 0.0}, r, 1.0, steel, {2.0, 0.0});  // the striker
    for (int i = 0; i < 4; ++i) s.circle({2.0 * r * i, 0.0}, r, 1.0, steel);
    if (!from_left) s.circle({6.0 * r + 0.21, 0.0}, r, 1.0, steel, {-2.0, 0.0});
    const int n = s.world.model.body_count();
    const int far = from_left ? n - 1 : 0;
    World<2>& w = s.finish();
    CHECK(w.step());
    // exact but for round-off of the passes (1e-15 measured)
    for (int i = 0; i < n; ++i)
      if (i != far) CHECK_NEAR(w.state.body_v[i].x, 0.0, 1e-12);
    CHECK_NEAR(w.state.body_v[far].x, from_left ? 2.0 : -2.0, 1e-12);
    double energy = 0.0;
    for (int i = 0; i < n; ++i) energy += 0.5 * length_squared(w.state.body_v[i]);
    CHECK_NEAR(energy, 2.0, 1e-12);  // J: e = 1 keeps the kinetic energy
  }
}

// Below the restitution threshold an elastic impact is only stopped (a ball does not
// jitter at rest): 0.5 m/s < 1 m/s ends with both balls at the common velocity.
TEST(impact_below_threshold_is_inelastic) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  const Material mat{0.0, 1.0};
  const int b1 = s.circle({-0.251, 0.0}, 0.25, 1.0, mat, {0.5, 0.0});
  const int b2 = s.circle({0.251, 0.0}, 0.25, 1.0, mat);
  World<2>& w = s.finish();
  for (int k = 0; k < 10; ++k) CHECK(w.step());
  CHECK_NEAR(w.state.body_v[b1].x, 0.25, 1e-9);
  CHECK_NEAR(w.state.body_v[b2].x, 0.25, 1e-9);
}

// A box (0.6 m, 1 kg) falls flat at 4 m/s, without gravity, onto the joint of two static
// segments, 0.1 m to one side of its centre (restitution.cpp, push_group): the two
// segments' manifolds are one block, and the box leaves at e times 4 m/s, not turning,
// as from one floor. (Each manifold alone, its points all on one side of the centre, it
// was bounced corner by corner and tipped: it left at 3.68 m/s turning at 6.4 rad/s for
// e = 1, at 1.52 m/s and 3.6 rad/s for e = 0.5, and at 0.1 m/s, 0.33 rad/s for e = 0.)
TEST(box_landing_across_two_segments_bounces_as_from_one) {
  for (const double e : {1.0, 0.5, 0.0}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    const Material mat{0.0, e};
    s.segment({-2.0, 0.0}, {0.0, 0.0}, mat);
    s.segment({0.0, 0.0}, {2.0, 0.0}, mat);
    const int box = s.box({0.1, 0.31}, 0.3, 0.3, 1.0, mat, 0.0, {0.0, -4.0});
    World<2>& w = s.finish();
    for (int k = 0; k < 10; ++k) CHECK(w.step());
    // m/s and rad/s: the block's regularisation of the seam's dependent rows (BLOCK_EPS of
    // the diagonal; 4e-9 m/s and 7e-9 rad/s measured)
    CHECK_NEAR(w.state.body_v[box].y, 4.0 * e, 1e-7);
    CHECK_NEAR(w.state.body_v[box].x, 0.0, 1e-7);
    CHECK_NEAR(w.state.body_w[box], 0.0, 1e-7);
  }
}

// A disk (r = 0.5 m, 1 kg, v = (4, 3) m/s, no spin, μ = 0.69, e = 0.5) strikes a static
// wall 2 cm away, less than a substep's travel after the next: the speculative push
// stops it at the wall, and the bounce waits until it is there. The impact sticks: the
// disk leaves with v = (−e 4, 2) m/s, ω = −4 rad/s (friction solved against the whole
// normal impulse, 6 N·s, not the part the soft solve delivered), and it turned back at
// the wall, not before it.
TEST(wall_impact_waits_for_the_wall_and_takes_friction_with_its_whole_impulse) {
  for (const double gap : {0.02, 0.013, 0.031}) {  // m: the impact in other substeps
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    const Material rough{0.69, 0.5};
    s.segment({2.0, -10.0}, {2.0, 10.0}, rough);
    const int disk = s.circle({1.5 - gap, 0.0}, 0.5, 1.0, rough, {4.0, 3.0});
    World<2>& w = s.finish();
    const double dt = w.config.dt;
    double x_before = 0.0, t_before = 0.0, t = 0.0;
    for (int k = 0; k < 6; ++k) {
      const double x = w.state.body_x[disk].x;
      if (w.state.body_v[disk].x == 4.0) x_before = x, t_before = t;
      CHECK(w.step());
      t += dt;
    }
    const Vec2 v = w.state.body_v[disk];
    CHECK_NEAR(v.x, -2.0, 1e-9);  // e = 0.5 of the 4 m/s approach
    CHECK_NEAR(v.y, 2.0, 1e-9);  // the contact point stopped: v_t + ω r = 0
    CHECK_NEAR(w.state.body_w[disk], -4.0, 1e-9);
    // the turning point: the line before the impact meets the line after it
    const double x_end = w.state.body_x[disk].x;
    const double meet = (x_end - x_before - v.x * t + 4.0 * t_before) / (4.0 - v.x);
    const double turn = x_before + 4.0 * (meet - t_before) + 0.5;  // m: the disk's surface
    CHECK(turn > 2.0 - constants::IMPACT_GAP);
  }
}

// A disk spinning at 300 rad/s into the same wall slides on it: friction takes μ times
// the normal impulse, J_t = −0.69 (1 + e) 4 N·s, and with e = 0 the disk stays at the wall
// (it once jumped back 9 cm: its turning contact point was taken for one that moves).
TEST(spinning_disk_slides_on_the_wall_with_mu_times_the_normal_impulse) {
  for (const double e : {0.0, 0.5}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    const Material rough{0.69, e};
    s.segment({2.0, -10.0}, {2.0, 10.0}, rough);
    const int disk = s.circle({1.45, 0.0}, 0.5, 1.0, rough, {4.0, 0.0}, 300.0);
    World<2>& w = s.finish();
    double x_max = 0.0;
    for (int k = 0; k < 6; ++k) {
      CHECK(w.step());
      x_max = std::max(x_max, w.state.body_x[disk].x);
      if (e == 0.0) CHECK(w.state.body_x[disk].x > x_max - 1e-9);  // never moves back
    }
    const double jt = -0.69 * (1.0 + e) * 4.0;  // N·s
    CHECK_NEAR(w.state.body_v[disk].x, -4.0 * e, 1e-9);
    CHECK_NEAR(w.state.body_v[disk].y, jt, 1e-9);
    CHECK_NEAR(w.state.body_w[disk], 300.0 + jt * 0.5 / 0.125, 1e-9);  // Δω = J_t r / I
    if (e == 0.0) CHECK(x_max > 1.5 - constants::IMPACT_GAP);  // it reached the wall
  }
}

namespace {

// Two 3D bodies with full inertia tensors, turned, spinning, struck off-centre: a 2 kg
// body and a 3 kg one meeting at a point away from both COMs, no gravity, no friction.
struct OffCentre {
  rbsim::test::Builder3 s;
  int a = 0, b = 0;
  Vec3 n, ra, rb;
};
void off_centre(OffCentre& o, double e) {
  using rbsim::test::about;
  const Sym3 ia{0.30, 0.45, 0.60, 0.05, -0.03, 0.02};  // kg·m², body frame, not diagonal
  const Sym3 ib{0.80, 0.50, 0.70, -0.04, 0.06, 0.01};
  o.a = o.s.body({0.1, 0.6, -0.2}, 2.0, ia, about({1, 2, 3}, 0.7), {0.3, -2.0, 0.5},
                 {1.0, -0.5, 2.0});
  o.b = o.s.body({-0.2, -0.5, 0.1}, 3.0, ib, about({-2, 1, 0.5}, 1.1), {-0.1, 1.0, 0.2},
                 {-0.3, 0.8, 0.4});
  World<3>& w = o.s.finish();
  o.n = (1.0 / length(Vec3{0.1, 1.0, 0.05})) * Vec3{0.1, 1.0, 0.05};
  const Vec3 p{0.35, 0.02, 0.25};  // the contact point (world, m)
  o.s.manifold(o.a, o.b, o.n, {p}, 0.0, e);
  o.ra = p - w.state.body_x[o.a];
  o.rb = p - w.state.body_x[o.b];
  o.s.prepare();
}

}  // namespace

// An isolated collision of two 3D bodies, off-centre, with the full world inverse
// inertia tensors: the restitution stage applies γ = −(1 + e) m_eff v_n⁻ with
// m_eff⁻¹ = 1/m_a + 1/m_b + n·((I_a⁻¹(r_a×n))×r_a) + n·((I_b⁻¹(r_b×n))×r_b), and
// v_n⁺ = −e v_n⁻, to round-off, for e = 0, 0.5 and 1.
TEST(isolated_collision_3d_matches_restitution_formula) {
  for (const double e : {0.0, 0.5, 1.0}) {
    OffCentre o;
    off_centre(o, e);
    World<3>& w = o.s.world;
    const auto& m = w.model;
    const Vec3 n = o.n;
    const Vec3 ka = cross(rbsim::test::world_apply(w.state.body_q[o.a], m.body_inv_inertia[o.a],
                                                   cross(o.ra, n)), o.ra);
    const Vec3 kb = cross(rbsim::test::world_apply(w.state.body_q[o.b], m.body_inv_inertia[o.b],
                                                   cross(o.rb, n)), o.rb);
    const double m_eff = 1.0 / (1.0 / 2.0 + 1.0 / 3.0 + dot(n, ka) + dot(n, kb));  // kg
    const double vn_before = dot(rbsim::test::point_velocity3(w, 0, 0), n);
    CHECK(vn_before < -1.0);  // faster than the restitution threshold
    const Vec3 pa = 2.0 * w.state.body_v[o.a], la = w.state.body_l[o.a];
    const Vec3 lb = w.state.body_l[o.b];
    const double h = rbsim::test::substep(w);
    const double threshold = 1.0;  // m/s
    solve_contacts(w.model, w.state, w.contacts, 1.0 / h, true, 0.0, threshold,
                   w.contacts.solve_order.data(), 1);
    apply_restitution(w.model, w.state, w.contacts, threshold, h, 1.0);
    const double gamma = -(1.0 + e) * m_eff * vn_before;  // N·s
    const Vec3 dp = 2.0 * w.state.body_v[o.a] - pa;      // the impulse on a (N·s)
    // round-off: the impulse is a few N·s, each of its terms a few ulps of its size
    CHECK_NEAR(dot(dp, n), gamma, 1e-13 * std::fabs(gamma));
    CHECK_NEAR(length(dp - dot(dp, n) * n), 0.0, 1e-13 * std::fabs(gamma));
    CHECK_NEAR(dot(rbsim::test::point_velocity3(w, 0, 0), n), -e * vn_before, 1e-13);
    // the angular impulses r × γn, into L; and ω = R I_b⁻¹ Rᵀ L
    CHECK_NEAR(length(w.state.body_l[o.a] - la - cross(o.ra, gamma * n)), 0.0, 1e-13);
    CHECK_NEAR(length(w.state.body_l[o.b] - lb + cross(o.rb, gamma * n)), 0.0, 1e-13);
    const Vec3 wa = rbsim::test::world_apply(w.state.body_q[o.a], m.body_inv_inertia[o.a],
                                             w.state.body_l[o.a]);
    CHECK_NEAR(length(w.state.body_w[o.a] - wa), 0.0, 1e-14);
    // momentum is kept (N·s)
    const Vec3 p_total = 2.0 * w.state.body_v[o.a] + 3.0 * w.state.body_v[o.b];
    CHECK_NEAR(length(p_total - Vec3{0.3, -1.0, 1.6}), 0.0, 1e-13);
  }
}

// An e = 1 collision of the two 3D bodies keeps their kinetic energy, translational and
// rotational (½ L·ω), to round-off.
TEST(elastic_collision_3d_keeps_kinetic_energy) {
  OffCentre o;
  off_centre(o, 1.0);
  World<3>& w = o.s.world;
  auto energy = [&] {
    double e = 0.0;
    for (int i : {o.a, o.b})
      e += 0.5 * w.model.body_mass[i] * dot(w.state.body_v[i], w.state.body_v[i]) +
           0.5 * dot(w.state.body_l[i], w.state.body_w[i]);
    return e;
  };
  const double before = energy();
  const double h = rbsim::test::substep(w);
  solve_contacts(w.model, w.state, w.contacts, 1.0 / h, true, 0.0, 1.0,
                 w.contacts.solve_order.data(), 1);
  apply_restitution(w.model, w.state, w.contacts, 1.0, h, 1.0);
  CHECK_NEAR(energy(), before, 1e-13 * before);  // J: round-off of a few J
}

RBSIM_TEST_MAIN
