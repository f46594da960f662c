// solver/solve.cpp: one sequential-impulse pass on contacts whose answer is known: an
// isolated impact, a closing gap, a resting box's face, Coulomb's cone.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "check.hpp"
#include "contacts3d_builder.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

namespace {

constexpr double NO_BOUNCE = std::numeric_limits<double>::infinity();  // m/s threshold

// One solver pass over every manifold: with the soft bias (the solve stage) or without (relax).
void solve_pass(World<2>& w, bool use_bias) {
  solve_contacts(w.model, w.state, w.contacts, 1.0 / rbsim::test::substep(w), use_bias, 0.0,
                 NO_BOUNCE, w.contacts.solve_order.data(), w.contacts.count.manifolds);
}

// Two balls approaching head-on, m1 = 1 kg at +2 m/s and m2 = 3 kg at -1 m/s, overlapping
// by 1 µm, no gravity.
World<2>& head_on(SceneBuilder& s) {
  s.world.model.gravity = {0.0, 0.0};
  s.circle({-0.25, 0.0}, 0.25 + 0.5e-6, 1.0, {0.0, 0.0}, {2.0, 0.0});
  s.circle({0.25, 0.0}, 0.25 + 0.5e-6, 3.0, {0.0, 0.0}, {-1.0, 0.0});
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  return w;
}

}  // namespace

// An isolated two-body impact with e = 0: the rigid pass (relax) applies
// γ = −(1 + e) m_eff v_n⁻ with m_eff = m1 m2 / (m1 + m2), which ends the approach and
// keeps the momentum.
TEST(isolated_collision_impulse_is_restitution_formula_for_e_zero) {
  SceneBuilder s;
  World<2>& w = head_on(s);
  CHECK(w.contacts.count.manifolds == 1);
  const double vn_before = rbsim::test::point_normal_velocity(w, 0, 0);
  CHECK_NEAR(vn_before, -3.0, 1e-15);
  solve_pass(w, false);
  const double m_eff = 1.0 * 3.0 / 4.0;  // kg
  CHECK_NEAR(w.contacts.normal_impulse[0][0], -m_eff * vn_before, 1e-14);
  CHECK_NEAR(rbsim::test::point_normal_velocity(w, 0, 0), 0.0, 1e-14);
  CHECK_NEAR(1.0 * w.state.body_v[0].x + 3.0 * w.state.body_v[1].x, -1.0, 1e-14);  // N·s
  CHECK_NEAR(w.state.body_v[0].x, -0.25, 1e-14);  // the common velocity, (2 − 3) / 4 m/s
}

// A gap closes within the substep and no further (speculative contact): after the solve
// stage the normal velocity is −gap / h.
TEST(speculative_gap_closes_exactly_in_one_substep) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.box({0, -0.5}, 2.0, 0.5, 0.0);
  const double gap = 0.004;  // m
  const int ball = s.circle({0.0, 0.25 + gap}, 0.25, 1.0, {}, {0.0, -5.0});
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  CHECK(w.contacts.count.manifolds == 1);
  solve_pass(w, true);
  const double h = rbsim::test::substep(w);
  CHECK_NEAR(w.state.body_v[ball].y, -gap / h, 1e-12);
  // a slow approach that cannot close the gap is left alone
  w.state.body_v[ball] = {0.0, -0.5 * gap / h};
  w.contacts.normal_impulse[0][0] = 0.0;
  solve_pass(w, true);
  CHECK(w.state.body_v[ball].y == -0.5 * gap / h);
}

// A box resting flat on the ground: the 2x2 block solve gives its two points mirror-image
// impulses, so gravity's step leaves no spin.
TEST(resting_box_points_get_mirror_image_impulses) {
  SceneBuilder s;
  s.ground();
  const int box = s.box({0.0, 0.5}, 0.5, 0.5, 2.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  CHECK(w.contacts.points[0] == 2);
  const double h = rbsim::test::substep(w);
  integrate_velocities(w.model, w.state, h);
  warm_start(w.model, w.state, w.contacts);
  solve_pass(w, true);
  const auto& lam = w.contacts.normal_impulse[0];
  CHECK(lam[0] > 0.0);
  CHECK_NEAR(lam[0], lam[1], 1e-15);           // N·s: round-off of ~0.05
  CHECK_NEAR(w.state.body_w[box], 0.0, 1e-14);  // rad/s
}

// Coulomb's law: a box sliding fast has each point's friction impulse at the cone,
// |λt| = μ λn, and slows; one barely creeping is stopped, inside the cone.
TEST(friction_impulse_is_clamped_to_coulomb_cone) {
  for (const double speed : {3.0, 1e-3}) {
    SceneBuilder s;
    s.ground(-10, 10, {0.3, 0.0});
    const int box = s.box({0.0, 0.5}, 0.5, 0.5, 1.0, {0.3, 0.0}, 0.0, {speed, 0.0});
    World<2>& w = s.finish();
    rbsim::test::collide(w);
    const double mu = w.contacts.friction[0];
    CHECK_NEAR(mu, 0.3, 1e-15);
    integrate_velocities(w.model, w.state, rbsim::test::substep(w));
    solve_pass(w, true);
    const auto& lt = w.contacts.tangent_impulse[0];
    const auto& ln = w.contacts.normal_impulse[0];
    for (int k = 0; k < 2; ++k) CHECK(std::fabs(lt[k]) <= mu * ln[k] * (1.0 + 1e-15));
    if (speed > 1.0) {
      for (int k = 0; k < 2; ++k) CHECK_NEAR(std::fabs(lt[k]), mu * ln[k], 1e-15);
      CHECK(w.state.body_v[box].x < speed && w.state.body_v[box].x > 0.0);
    } else {
      CHECK(std::fabs(lt[0]) + std::fabs(lt[1]) < mu * (ln[0] + ln[1]));  // inside the cone
      // Gauss-Seidel over the two points: each pass takes most of the creep away
      for (int it = 0; it < 30; ++it) solve_pass(w, false);
      CHECK_NEAR(w.state.body_v[box].x, 0.0, 1e-9);  // m/s: stuck
    }
  }
}

// 2D: the passes around a deep overlap run in the waves' batches, only the lanes of the
// region's manifolds solved (deep_region_lanes, solve_batch_lanes); they are the passes
// over deep_region's list one manifold at a time (to the rounding of the multiply-adds the
// compiler fuses in the lanes' code and in the one-at-a-time code alike or not,
// -ffp-contract=fast), and leave every other manifold's bodies as they are. A column of
// boxes whose second box is 3 cm into the first, falling onto it, and a second column
// beside it, joined only through the ground (a push does not travel through it), and so
// outside the region; without the bias only the contacts still closing.
TEST(deep_region_in_the_batches_lanes_is_the_region_one_by_one) {
  auto scene = [](SceneBuilder& s) -> World<2>& {
    s.world.model.gravity = {0.0, -10.0};
    s.ground();
    s.box({-3.0, 0.5}, 0.5, 0.5, 1.0);
    s.box({-3.0, 1.47}, 0.5, 0.5, 1.0, {}, 0.0, {0.0, -1.0});    // 3 cm into the first
    s.box({-3.02, 2.47}, 0.5, 0.5, 2.0, {}, 0.0, {0.1, -1.2});
    s.circle({-3.0, 3.21}, 0.25, 0.5, {}, {0.0, -0.8});
    s.box({3.0, 0.5}, 0.5, 0.5, 1.0, {}, 0.0, {0.0, -0.5});      // the other column
    s.box({3.0, 1.5}, 0.5, 0.5, 1.0, {}, 0.0, {0.2, -0.7});
    s.circle({3.0, 2.245}, 0.25, 0.5, {}, {0.0, -0.9});
    return s.finish();
  };
  constexpr int DEEP_A = 1, DEEP_B = 2;  // the deep overlap's bodies
  constexpr int OTHER[] = {5, 6, 7};    // the other column's
  for (const bool use_bias : {false, true}) {
    SceneBuilder s0, s1;
    World<2>& one = scene(s0);
    World<2>& lanes = scene(s1);
    std::int32_t deep = -1;
    for (World<2>* w : {&one, &lanes}) {
      rbsim::test::collide(*w);
      auto& c = w->contacts;
      for (std::int64_t m = 0; m < c.count.manifolds; ++m)
        if (c.body_a[m] + c.body_b[m] == DEEP_A + DEEP_B && c.body_a[m] * c.body_b[m] == 2)
          deep = static_cast<std::int32_t>(m);
      CHECK(deep >= 0);
      // the solve pass met it, and the box has moved this step (it seeds the region)
      c.relax_list[0] = deep;
      c.count.deep_count = 1;
      c.body_delta[DEEP_B].dx = {0.0, -0.01};
    }
    const std::vector<Vec2> v_before = one.state.body_v;
    const double inv_h = 1.0 / rbsim::test::substep(one);
    // m/s: without the bias (deep_solve's first passes), only the contacts closing faster
    const double min_approach = use_bias ? 0.0 : constants::SHOCK_MIN_APPROACH;
    auto& c1 = one.contacts;
    std::int64_t n = deep_region(one.model, c1, constants::DEEP_RELAX_REACH);
    CHECK(n >= 3 && n < c1.count.manifolds);  // the first column's contacts, not the other's
    if (min_approach > 0.0) n = keep_closing(one.state, c1, c1.relax_list.data(), n, min_approach);
    CHECK(n >= 2);
    solve_contacts(one.model, one.state, c1, inv_h, use_bias, 0.0, NO_BOUNCE, c1.relax_list.data(),
                   n);
    auto& c2 = lanes.contacts;
    find_waves(lanes.model, c2);
    std::vector<BatchLanes> region(static_cast<std::size_t>(c2.wave_batch[c2.wave_count]));
    const std::int64_t n_batches = deep_region_lanes(lanes.model, lanes.state, c2,
                                                     constants::DEEP_RELAX_REACH, min_approach,
                                                     region.data());
    int n_lanes = 0;
    for (std::int64_t i = 0; i < n_batches; ++i)
      n_lanes += std::popcount(unsigned{region[i].lanes});
    CHECK(n_lanes == n);
    take_impulses(c2);
    PassLog log = PassLog::direct(c2);
    solve_batch_lanes(lanes.state, c2, inv_h, use_bias, 0.0, NO_BOUNCE, region.data(), n_batches,
                      log);
    give_impulses(c2);
    double changed = 0.0;  // m/s
    for (int i = 0; i < one.model.body_count(); ++i) {
      CHECK_NEAR(lanes.state.body_v[i].x, one.state.body_v[i].x, 1e-12);
      CHECK_NEAR(lanes.state.body_v[i].y, one.state.body_v[i].y, 1e-12);
      CHECK_NEAR(lanes.state.body_w[i], one.state.body_w[i], 1e-12);
      changed = std::max(changed, length(lanes.state.body_v[i] - v_before[i]));
    }
    CHECK(changed > 0.1);
    for (const int i : OTHER) {  // outside the region: untouched, to the bit
      CHECK(lanes.state.body_v[i].x == v_before[i].x && lanes.state.body_v[i].y == v_before[i].y);
      CHECK(lanes.state.body_w[i] == 0.0);
    }
    for (std::int64_t m = 0; m < c1.count.manifolds; ++m)
      for (int k = 0; k < c1.points[m]; ++k)
        CHECK_NEAR(c2.normal_impulse[m][k], c1.normal_impulse[m][k], 1e-12);
  }
}

namespace {

// Whether lane l of batch B (of two-point manifolds: `two`) holds manifold m's row
// (c.solver_row[m]) and bodies, field by field, or, for m < 0, an empty lane (zeros, K 1,
// body 0, not written). A one-point batch's second point is never read: not compared.
bool lane_holds(const World<2>& w, const WideBatch& B, bool two, int l, std::int32_t m) {
  const auto& c = w.contacts;
  if (m < 0) {
    const double* zeros[] = {&B.nx[l], &B.ny[l], &B.k01[l], &B.gamma[l], &B.bias_rate[l],
                             &B.friction[l], &B.load[l], &B.ma[l], &B.mb[l], &B.ia[l],
                             &B.ib[l], &B.two[l], &B.p0.rna[l], &B.p0.base[l],
                             two ? &B.p1.rax[l] : &B.p0.rax[l]};
    bool ok = B.m[l] == -1 && B.live[l] == 0 && B.a[l] == 0 && B.b[l] == 0;
    for (const double* z : zeros) ok = ok && *z == 0.0;
    return ok && B.p0.kn[l] == 1.0 && (!two || B.p1.kn[l] == 1.0) && (B.writes >> l & 1u) == 0 &&
           (B.writes >> (LANES + l) & 1u) == 0;
  }
  const SolverRow<2>& r = c.solver_row[m];
  const int a = c.body_a[m], b = c.body_b[m];
  bool ok = two == (c.points[m] == 2) && B.m[l] == m && B.live[l] == -1 && B.a[l] == a &&
            B.b[l] == b;
  ok = ok && B.nx[l] == r.normal.x && B.ny[l] == r.normal.y && B.k01[l] == r.k01 &&
       B.gamma[l] == r.gamma && B.bias_rate[l] == r.bias_rate && B.friction[l] == r.friction &&
       B.load[l] == r.friction_load && B.max_push[l] == r.max_push && B.deep[l] == r.deep &&
       B.touch[l] == r.touch && B.two[l] == (two ? 1.0 : 0.0);
  ok = ok && B.ma[l] == w.model.body_inv_mass[a] && B.mb[l] == w.model.body_inv_mass[b] &&
       B.ia[l] == w.model.body_inv_inertia[a] && B.ib[l] == w.model.body_inv_inertia[b];
  ok = ok && (B.writes >> l & 1u) == (w.model.is_dynamic(a) ? 1u : 0u) &&
       (B.writes >> (LANES + l) & 1u) == (w.model.is_dynamic(b) ? 1u : 0u);
  for (int k = 0; k < (two ? 2 : 1); ++k) {
    const WidePoint& p = k == 0 ? B.p0 : B.p1;
    const auto& q = r.point[k];
    ok = ok && p.rna[l] == q.rna && p.rnb[l] == q.rnb && p.rta[l] == q.rta && p.rtb[l] == q.rtb &&
         p.kn[l] == q.kn && p.tangent_mass[l] == q.tangent_mass && p.rax[l] == q.ra.x &&
         p.ray[l] == q.ra.y && p.rbx[l] == q.rb.x && p.rby[l] == q.rb.y && p.base[l] == q.base;
  }
  return ok;
}

// Every lane of every batch: its manifold's row, or empty; every manifold in one lane.
void check_batches_hold_rows(const World<2>& w) {
  const auto& c = w.contacts;
  std::vector<int> seen(static_cast<std::size_t>(c.count.manifolds), 0);
  for (std::int64_t i = 0; i < c.wave_batch[c.wave_count]; ++i) {
    const WideBatch& B = c.batches[i];
    const bool two = i < c.wave_single_batch[i];  // (each batch a wave: find_waves)
    for (int l = 0; l < LANES; ++l) {
      CHECK(lane_holds(w, B, two, l, B.m[l]));
      if (B.m[l] >= 0) ++seen[B.m[l]];
    }
  }
  for (const int n : seen) CHECK(n == 1);
}

}  // namespace

// The batches are packed from the rows four at a time (waves.cpp, pack_batch): every
// field of every lane is its manifold's, in a pile of boxes (two points) and balls (one),
// with rows of distinct values (no field can stand for another) and shapes below unit
// scale (the rows' own push-out bounds are packed); and again, the graph unchanged, where
// the rows of the manifolds not carried changed (packed again whole) and the carried ones'
// base separations and friction loads did.
TEST(every_lane_of_the_batches_holds_its_manifolds_row) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, -10.0};
  s.ground(-5.0, 5.0);
  for (int i = 0; i < 5; ++i) {
    s.box({-2.0 + 0.01 * i, 0.025 + 0.05 * i}, 0.025, 0.025, 1.0);  // two leaning columns
    s.box({-1.0 - 0.01 * i, 0.025 + 0.05 * i}, 0.025, 0.025, 1.0);
    s.circle({1.0 + 0.05 * i, 0.02}, 0.02, 0.5);                     // a row of balls
    s.circle({1.0 + 0.05 * i + 0.025, 0.055}, 0.02, 0.5);            // and one above
  }
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  auto& c = w.contacts;
  int ones = 0, twos = 0;
  for (std::int64_t m = 0; m < c.count.manifolds; ++m) (c.points[m] == 2 ? twos : ones) += 1;
  CHECK(ones >= 5 && twos >= 8);
  CHECK(!c.unit_scale);
  auto distinct_rows = [&c](double salt) {
    for (std::int64_t m = 0; m < c.count.manifolds; ++m) {
      double* d = reinterpret_cast<double*>(&c.solver_row[m]);
      for (int j = 0; j < 32; ++j) d[j] = salt + 100.0 * static_cast<double>(m) + j + 0.5;
    }
  };
  distinct_rows(0.0);
  partition_regions(w.model, w.state, c);
  find_waves(w.model, c);
  check_batches_hold_rows(w);
  // the same graph a step later: half the manifolds carried
  for (std::int64_t m = 0; m < c.count.manifolds; ++m) c.carried[m] = m % 2;
  const std::vector<SolverRow<2>> before(c.solver_row.begin(),
                                         c.solver_row.begin() + c.count.manifolds);
  distinct_rows(0.25);
  for (std::int64_t m = 0; m < c.count.manifolds; ++m) {
    if (!c.carried[m]) continue;  // a carried row: only these two fields change
    const double base0 = c.solver_row[m].point[0].base, base1 = c.solver_row[m].point[1].base;
    const double load = c.solver_row[m].friction_load;
    c.solver_row[m] = before[m];
    c.solver_row[m].point[0].base = base0;
    c.solver_row[m].point[1].base = base1;
    c.solver_row[m].friction_load = load;
  }
  c.count.graph_unchanged = 1;
  find_waves(w.model, c);
  check_batches_hold_rows(w);
}

namespace {

using rbsim::test::about;
using rbsim::test::Builder3;

// One 3D pass over every manifold, rigid (the relax stage) unless use_bias.
void solve_pass3(World<3>& w, bool use_bias) {
  solve_contacts(w.model, w.state, w.contacts, 1.0 / rbsim::test::substep(w), use_bias, 0.0,
                 NO_BOUNCE, w.contacts.solve_order.data(), w.contacts.count.manifolds);
}

// A body with a full inertia tensor, turned and spinning, striking the static ground
// (normal +y) at a point off its centre, sliding along (1, 0, 1)/√2 (45° to the row's
// tangents) at `slide` m/s; the whole scene turned by phi about the normal.
struct Strike {
  Builder3 s;
  int body = 0, ground = 0;
  Quat turn;
};
void strike(Strike& t, double slide, double mu, double phi) {
  t.turn = about({0, 1, 0}, phi);
  auto r = [&](Vec3 v) { return rotate(t.turn, v); };
  const Sym3 inertia{0.30, 0.45, 0.60, 0.05, -0.03, 0.02};  // kg·m², body frame
  const double k = slide / std::sqrt(2.0);
  t.body = t.s.body(r({0.1, 0.5, -0.1}), 2.0, inertia, mul(t.turn, about({1, 2, 3}, 0.7)),
                    r({k, -3.0, k}), r({0.4, -0.2, 0.3}));
  t.ground = t.s.fixed({0, 0, 0});
  t.s.finish();
  t.s.manifold(t.body, t.ground, {0, 1, 0}, {r({0.3, 0.0, 0.1})}, mu, 0.0);
  t.s.prepare();
}

}  // namespace

// 3D friction at a sticking impact: the rigid pass stops the approach, then the point's
// 2×2 friction block stops its sliding in both tangent directions at once, within the cone.
TEST(friction_3d_sticking_impact_stops_the_slide) {
  Strike t;
  strike(t, 0.4, 1.0, 0.0);
  World<3>& w = t.s.world;
  solve_pass3(w, false);
  const Vec3 u = rbsim::test::point_velocity3(w, 0, 0);
  CHECK_NEAR(u.x, 0.0, 1e-14);  // m/s: round-off of velocities of a few m/s
  CHECK_NEAR(u.z, 0.0, 1e-14);
  const Vec3 jt = w.contacts.tangent_impulse[0][0];
  CHECK(length(jt) > 0.0);
  CHECK(length(jt) < 1.0 * w.contacts.normal_impulse[0][0]);  // inside the cone: sticking
  CHECK(jt.y == 0.0);  // in the tangent plane
}

// 3D friction while sliding: the friction impulse is μ λ_n, on Coulomb's circle (a
// four-sided pyramid would give √2 μ λ_n along this 45° slide), opposite the slip where
// the point's tangent block is isotropic (arm along the normal, isotropic inertia).
TEST(friction_3d_sliding_clamps_on_the_circle_against_the_slip) {
  Builder3 s;
  const double k = 2.0 / std::sqrt(2.0);
  const int ball = s.body({0, 0.5, 0}, 2.0, Sym3{0.2, 0.2, 0.2, 0, 0, 0}, about({1, 2, 3}, 0.7),
                          {k, -3.0, k});
  const int ground = s.fixed({0, 0, 0});
  World<3>& w = s.finish();
  const double mu = 0.1;  // the slide needs 1.14 N·s to stop; μ λ_n is 0.6
  s.manifold(ball, ground, {0, 1, 0}, {{0, 0, 0}}, mu, 0.0);
  s.prepare();
  solve_pass3(w, false);
  const double jn = w.contacts.normal_impulse[0][0];
  const Vec3 jt = w.contacts.tangent_impulse[0][0];
  CHECK_NEAR(jn, 2.0 * 3.0, 1e-13);  // N·s: m v_n, the arm along n adds no turn
  CHECK_NEAR(length(jt), mu * jn, 1e-13);
  CHECK_NEAR(jt.x / length(jt), -1.0 / std::sqrt(2.0), 1e-15);  // against the slip
  CHECK_NEAR(jt.z / length(jt), -1.0 / std::sqrt(2.0), 1e-15);
  CHECK(rbsim::test::point_velocity3(w, 0, 0).x > 0.0);  // still sliding
}

// Sliding off the centre of mass, where the point's tangent block is anisotropic (full
// tensor, arm not along the normal): the friction impulse still points against the slip,
// the point's sliding velocity that the normal impulse leaves (the same pass without
// friction gives it), with magnitude μ λ_n.
TEST(friction_3d_sliding_off_centre_points_against_the_slip) {
  Strike free, t;
  strike(free, 2.0, 0.0, 0.0);
  strike(t, 2.0, 0.05, 0.0);
  solve_pass3(free.s.world, false);
  solve_pass3(t.s.world, false);
  Vec3 slip = rbsim::test::point_velocity3(free.s.world, 0, 0);
  slip.y = 0.0;  // the tangent plane's part (normal +y)
  const Vec3 jt = t.s.world.contacts.tangent_impulse[0][0];
  const double jn = t.s.world.contacts.normal_impulse[0][0];
  CHECK_NEAR(jn, free.s.world.contacts.normal_impulse[0][0], 1e-14);  // N·s
  CHECK_NEAR(length(jt), 0.05 * jn, 1e-14);
  // round-off of unit vectors
  CHECK_NEAR(length((1.0 / length(jt)) * jt + (1.0 / length(slip)) * slip), 0.0, 1e-14);
}

// Friction is isotropic: the same strike turned about the normal by any angle gives the
// same impulses and velocities turned by that angle, to round-off, sticking or sliding
// (the row's tangent basis does not turn with the scene).
TEST(friction_3d_is_the_same_for_any_tangent_basis) {
  for (const double mu : {1.0, 0.2}) {
    Strike t0;
    strike(t0, 2.0, mu, 0.0);
    solve_pass3(t0.s.world, false);
    for (const double phi : {0.3, 0.785398, 1.9, -2.5}) {
      Strike t;
      strike(t, 2.0, mu, phi);
      World<3>& w = t.s.world;
      solve_pass3(w, false);
      const auto& c0 = t0.s.world.contacts;
      const State<3>& s0 = t0.s.world.state;
      auto back = [&](Vec3 v) { return inv_rotate(t.turn, v); };
      // round-off of impulses and velocities of a few N·s and m/s
      CHECK_NEAR(w.contacts.normal_impulse[0][0], c0.normal_impulse[0][0], 1e-13);
      CHECK_NEAR(length(back(w.contacts.tangent_impulse[0][0]) - c0.tangent_impulse[0][0]), 0.0, 1e-13);
      CHECK_NEAR(length(back(w.state.body_v[0]) - s0.body_v[0]), 0.0, 1e-13);
      CHECK_NEAR(length(back(w.state.body_w[0]) - s0.body_w[0]), 0.0, 1e-13);
    }
  }
}

// A 1 m box of 1 kg resting flat on the ground on its four corners (one manifold of four
// points, solved as one block), turned about y by 0.4 rad: over 2 s of substeps (warm
// start, solve, positions, relax) gravity's push is held, the box neither sinks nor turns.
TEST(resting_box_3d_four_points_hold_it) {
  Builder3 s;
  s.world.model.gravity = {0.0, -9.81, 0.0};
  const double I = 1.0 / 6.0;  // kg·m²: m (a² + a²) / 12 for a 1 m cube
  const Quat q = about({0, 1, 0}, 0.4);
  const int box = s.body({0, 0.5, 0}, 1.0, Sym3{I, I, I, 0, 0, 0}, q);
  const int ground = s.fixed({0, 0, 0});
  World<3>& w = s.finish();
  std::vector<Vec3> corners;
  for (const Vec3 c : {Vec3{-0.5, -0.5, -0.5}, Vec3{0.5, -0.5, -0.5}, Vec3{0.5, -0.5, 0.5},
                       Vec3{-0.5, -0.5, 0.5}})
    corners.push_back(w.state.body_x[box] + rotate(q, c));
  s.manifold(box, ground, {0, 1, 0}, corners, 0.6, 0.0);
  s.prepare();
  const double h = rbsim::test::substep(w);
  auto& c = w.contacts;
  double max_vy = 0.0, max_w = 0.0;
  for (int step = 0; step < 120; ++step) {
    for (int sub = 0; sub < w.config.substeps; ++sub) {
      integrate_velocities(w.model, w.state, h);
      warm_start(w.model, w.state, c);
      solve_pass3(w, true);
      integrate_positions(w.model, w.state, c.body_delta, h, w.config.rotation,
                          Span{0, w.model.body_count()}, c.body_inv_inertia_world.data());
      solve_contacts(w.model, w.state, c, 1.0 / h, false, h, NO_BOUNCE, c.solve_order.data(), 1);
    }
    if (step >= 60) {  // after the first second, once the warm start has settled
      max_vy = std::max(max_vy, std::fabs(w.state.body_v[box].y));
      max_w = std::max(max_w, length(w.state.body_w[box]));
    }
  }
  // at rest and not turning, to round-off (the points solved one after the other left a
  // spin of 1e-8 rad/s and a drift of 3e-7 m in 2 s; gravity's substep is 0.04 m/s)
  CHECK(max_vy < 1e-12);  // m/s
  CHECK(max_w < 1e-12);   // rad/s
  CHECK(std::fabs(w.state.body_x[box].y - 0.5) < 1e-3);  // m: the soft contact's sag, < 1 mm
  CHECK(std::fabs(w.state.body_x[box].x) < 1e-12 && std::fabs(w.state.body_x[box].z) < 1e-12);
  // each corner carries a quarter of the weight, m g h per substep (N·s)
  for (int k = 0; k < 4; ++k) CHECK_NEAR(c.normal_impulse[0][k], 0.25 * 9.81 * h, 1e-6 * 9.81 * h);
}

namespace {

// Four pairs of unit cubes of 1 kg side by side along x, each pair's boxes touching on a
// face of `points` points (1, 2 or 4; normal −x, from the right box to the left), no
// gravity, no friction. The pairs' states, each made so that a pass asks a speed well
// under or over IDLE_SPEED (1e-10 m/s) of the face:
//   0: each point holds 1e-16 N·s (round-off), the boxes part at 1e-11 m/s: idle (a
//      solve would take the impulses to zero);
//   1: the same parting, but each point holds 4e-10 N·s (about 1e-9 m/s): busy;
//   2: round-off held (1e-16 N·s), the boxes close at 2e-10 m/s: busy;
//   3: round-off held, the boxes close at 0.5e-10 m/s: idle.
// (Every face holds an impulse, so that find_waves packs the four faces of two or four
// points in one batch of lanes: it leaves faces that hold nothing to the solve of one at
// a time.)
World<3>& side_by_side(Builder3& s, int points) {
  const double I = 1.0 / 6.0;  // kg·m²
  const double held[4] = {1e-16, 4e-10, 1e-16, 1e-16};  // N·s per point
  const double closing[4] = {-1e-11, -1e-11, 2e-10, 0.5e-10};  // m/s
  int box[4][2];
  for (int i = 0; i < 4; ++i) {
    const double x = 3.0 * i;
    box[i][0] = s.body({x, 0, 0}, 1.0, Sym3{I, I, I, 0, 0, 0}, {}, {closing[i], 0, 0});
    box[i][1] = s.body({x + 1.0, 0, 0}, 1.0, Sym3{I, I, I, 0, 0, 0});
  }
  World<3>& w = s.finish();
  const double ys[4] = {-0.5, 0.5, 0.5, -0.5}, zs[4] = {-0.5, -0.5, 0.5, 0.5};
  for (int i = 0; i < 4; ++i) {
    std::vector<Vec3> p;
    for (int k = 0; k < points; ++k)
      p.push_back({3.0 * i + 0.5, ys[k], points == 2 ? 0.0 : zs[k]});
    const std::int64_t m = s.manifold(box[i][0], box[i][1], {-1, 0, 0}, p, 0.0, 0.0);
    for (int k = 0; k < points; ++k) w.contacts.normal_impulse[m][k] = held[i];
  }
  s.prepare();
  return w;
}

bool same_state(const World<3>& a, const World<3>& b, int pair) {
  bool same = true;
  for (int j = 0; j < 2; ++j) {
    const int i = 2 * pair + j;
    const Vec3 va = a.state.body_v[i], vb = b.state.body_v[i];
    same = same && va.x == vb.x && va.y == vb.y && va.z == vb.z &&
           length(a.state.body_l[i] - b.state.body_l[i]) == 0.0;
  }
  for (int k = 0; k < 4; ++k)
    same = same && a.contacts.normal_impulse[pair][k] == b.contacts.normal_impulse[pair][k];
  return same;
}

}  // namespace

// An idle manifold (IDLE_SPEED: what its points hold and are asked is worth less than
// 1e-10 m/s) is left as it is by a pass, bit for bit; one asked or holding more is
// solved. Faces of four and two points and single points (four to a batch in vector
// lanes when the pass goes wave by wave, the same answer as in solve order).
TEST(idle_manifold_3d_is_left_as_it_is) {
  for (const int points : {4, 2, 1}) {
    for (const bool use_bias : {true, false}) {
      Builder3 s0, s1, s2;
      World<3>& before = side_by_side(s0, points);
      World<3>& w = side_by_side(s1, points);
      World<3>& waves = side_by_side(s2, points);
      solve_pass3(w, use_bias);
      CHECK(same_state(w, before, 0));
      CHECK(same_state(w, before, 3));
      CHECK(w.contacts.normal_impulse[1][0] < 4e-10);  // parting: the held impulse let go
      CHECK(w.contacts.normal_impulse[2][0] > 0.0);    // closing: stopped
      CHECK(w.state.body_v[4].x < 2e-10);
      // wave by wave: one wave of the four pairs, one batch in lanes
      find_waves(waves.model, waves.contacts);
      const auto& faces = waves.contacts.faces3;
      if (points > 1) CHECK(faces.size() == 1 && faces[0].count == points);
      if (points == 1) CHECK(faces.empty() && waves.contacts.batches3.size() == 1);
      solve_waves(waves.model, waves.state, waves.contacts, 1.0 / rbsim::test::substep(waves),
                  use_bias, 0.0, NO_BOUNCE);
      CHECK(same_state(waves, before, 0));
      CHECK(same_state(waves, before, 3));
      for (const int pair : {1, 2}) {
        const auto& lam = waves.contacts.normal_impulse[pair];
        for (int k = 0; k < points; ++k)  // N·s: round-off of impulses of 1e-10
          CHECK_NEAR(lam[k], w.contacts.normal_impulse[pair][k], 1e-24);
        CHECK_NEAR(waves.state.body_v[2 * pair].x, w.state.body_v[2 * pair].x, 1e-24);
      }
    }
  }
}

// A pyramid of 528 boxes, two regions: the manifolds of the cut between them (the centre
// column, each sharing a body with the next) go into spare lanes of the second region's
// batches, after their bodies' manifolds there. No batch holds two manifolds of one
// dynamic body; every body meets its region's manifolds before the cut's; and the passes
// over every batch whole (one thread) equal the threads' order to the bit: the first
// region, the second without the cut's lanes, then the cut's lanes and the cut's own
// batches.
TEST(a_cut_in_the_lanes_of_a_region_keeps_every_bodys_order) {
  auto scene = [](SceneBuilder& s) -> World<2>& {
    s.world.model.gravity = {0.0, -10.0};
    s.ground(-40.0, 40.0);
    constexpr int base = 32;  // 528 boxes: SOLVER_REGIONS regions of REGION_MIN_BODIES
    for (int row = 0, k = 0; row < base; ++row)
      for (int i = 0; i < base - row; ++i, ++k) {
        const Vec2 v = {0.02 * std::sin(0.7 * k), -0.3 + 0.05 * std::cos(1.3 * k)};  // m/s
        s.box({i - 0.5 * (base - row - 1), 0.5 + row}, 0.5, 0.5, 1.0, {}, 0.0, v);
      }
    return s.finish();
  };
  SceneBuilder s0, s1;
  World<2>& one = scene(s0);
  World<2>& threads = scene(s1);
  for (World<2>* w : {&one, &threads}) {
    rbsim::test::collide(*w);
    partition_regions(w->model, w->state, w->contacts);
    // impulses held from a step before, for the warm start (N·s)
    auto& cw = w->contacts;
    for (std::int64_t m = 0; m < cw.count.manifolds; ++m)
      for (int k = 0; k < cw.points[m]; ++k) {
        cw.normal_impulse[m][k] = 0.05 + 0.01 * static_cast<double>(m % 7);
        cw.tangent_impulse[m][k] = 0.002 * static_cast<double>(m % 5 - 2);
      }
    find_waves(w->model, w->contacts);
    take_impulses(w->contacts);
  }
  const auto& c = one.contacts;
  CHECK(c.region_count == 2 && c.cut_lanes);
  // where each manifold is among the batches, and the cut's lanes found
  std::vector<std::int64_t> at(static_cast<std::size_t>(c.count.manifolds), -1);
  int cut_lanes = 0;
  for (std::int64_t i = 0; i < c.wave_batch[c.wave_count]; ++i) {
    const WideBatch& B = c.batches[i];
    for (int l = 0; l < LANES; ++l) {
      if (B.m[l] < 0) continue;
      at[B.m[l]] = i;
      const int ra = c.body_region[B.a[l]], rb = c.body_region[B.b[l]];
      const bool joins = ra >= 0 && rb >= 0 && ra != rb;
      // a joining manifold is in a cut's lane of the second region's batches, or in the
      // cut's own batches after them
      const bool in_lane = (B.cut >> l & 1u) != 0;
      CHECK(joins == (in_lane || i >= c.segment_wave[2]));
      if (in_lane) CHECK(i >= c.segment_wave[1] && i < c.segment_wave[2]);
      cut_lanes += in_lane;
      for (int k = 0; k < l; ++k) {  // no dynamic body twice in a batch
        if (B.m[k] < 0) continue;
        for (const int x : {B.a[l], B.b[l]})
          if (one.model.is_dynamic(x)) CHECK(x != B.a[k] && x != B.b[k]);
      }
    }
  }
  CHECK(cut_lanes >= 20);  // (of the centre column's 78)
  // every body: its region's manifolds in earlier batches than any of its cut's
  for (int i = 0; i < one.model.body_count(); ++i) {
    if (!one.model.is_dynamic(i)) continue;
    std::int64_t last_own = -1, first_cut = std::numeric_limits<std::int64_t>::max();
    for (std::int64_t m = 0; m < c.count.manifolds; ++m) {
      if (c.body_a[m] != i && c.body_b[m] != i) continue;
      const int ra = c.body_region[c.body_a[m]], rb = c.body_region[c.body_b[m]];
      if (ra >= 0 && rb >= 0 && ra != rb)
        first_cut = std::min(first_cut, at[m]);
      else
        last_own = std::max(last_own, at[m]);
    }
    CHECK(last_own < first_cut);
  }
  // the passes: one thread's (every batch whole) against the threads' (segment by segment)
  const double inv_h = 1.0 / rbsim::test::substep(one);
  for (const bool use_bias : {true, false}) {
    PassLog log1 = PassLog::direct(one.contacts), log2 = PassLog::direct(threads.contacts);
    auto& c2 = threads.contacts;
    if (use_bias) {
      for (int g = 0; g < segment_count(2); ++g)
        warm_start_range(one.model, one.state, one.contacts, c.segment_wave[g], c.segment_wave[g + 1]);
      warm_start_range(threads.model, threads.state, c2, c2.segment_wave[0], c2.segment_wave[1]);
      warm_start_range(threads.model, threads.state, c2, c2.segment_wave[1], c2.segment_wave[2],
                       CutLanes::Without);
      warm_start_range(threads.model, threads.state, c2, c2.segment_wave[1], c2.segment_wave[2],
                       CutLanes::Only);
      warm_start_range(threads.model, threads.state, c2, c2.segment_wave[2], c2.wave_count);
    }
    for (int g = 0; g < segment_count(2); ++g)
      solve_wave_range(one.model, one.state, one.contacts, inv_h, use_bias, 0.0, NO_BOUNCE,
                       c.segment_wave[g], c.segment_wave[g + 1], log1);
    solve_wave_range(threads.model, threads.state, c2, inv_h, use_bias, 0.0, NO_BOUNCE,
                     c2.segment_wave[0], c2.segment_wave[1], log2);
    solve_wave_range(threads.model, threads.state, c2, inv_h, use_bias, 0.0, NO_BOUNCE,
                     c2.segment_wave[1], c2.segment_wave[2], log2, CutLanes::Without);
    solve_wave_range(threads.model, threads.state, c2, inv_h, use_bias, 0.0, NO_BOUNCE,
                     c2.segment_wave[1], c2.segment_wave[2], log2, CutLanes::Only);
    solve_wave_range(threads.model, threads.state, c2, inv_h, use_bias, 0.0, NO_BOUNCE,
                     c2.segment_wave[2], c2.wave_count, log2);
  }
  give_impulses(one.contacts);
  give_impulses(threads.contacts);
  double moved = 0.0;  // m/s
  for (int i = 0; i < one.model.body_count(); ++i) {
    CHECK(std::memcmp(&one.state.body_v[i], &threads.state.body_v[i], sizeof(Vec2)) == 0);
    CHECK(std::memcmp(&one.state.body_w[i], &threads.state.body_w[i], sizeof(double)) == 0);
    moved = std::max(moved, std::fabs(one.state.body_v[i].y + 0.3));
  }
  CHECK(moved > 0.1);  // (the passes did work)
  for (std::int64_t m = 0; m < c.count.manifolds; ++m)
    for (int k = 0; k < c.points[m]; ++k)
      CHECK(std::memcmp(&one.contacts.normal_impulse[m][k], &threads.contacts.normal_impulse[m][k],
                        sizeof(double)) == 0);
}

RBSIM_TEST_MAIN
