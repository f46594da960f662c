// dynamics/integrate.cpp: the same integrator in 2D and in 3D.
#include <cmath>
#include <cstring>

#include "check.hpp"
#include "rbsim/stages.hpp"

using namespace rbsim;

namespace {

template <int D>
void one_body(Model<D>& m, State<D>& s) {
  m.body_type = {BodyType::Dynamic};
  m.body_mass = {2.0};
  m.body_inv_mass = {0.5};
  m.body_com.resize(1);
  m.body_force.resize(1);
  m.body_force_arm.resize(1);
  m.body_torque.resize(1);
  s.body_x.resize(1);
  s.body_q.resize(1);
  s.body_v.resize(1);
  s.body_w.resize(1);
  if constexpr (D == 2) s.body_angle.resize(1);
  if constexpr (D == 3) s.body_l.resize(1);
}

}  // namespace

// Symplectic Euler: after n steps of h under gravity g from rest, y = -g h² n (n + 1) / 2.
TEST(projectile_matches_symplectic_euler_sum) {
  Model<2> m;
  State<2> s;
  one_body(m, s);
  m.body_inertia = {1.0};
  m.body_inv_inertia = {1.0};
  m.gravity = {0.0, -9.81};
  std::vector<BodyDelta<2>> delta(1);
  const double h = 0.01;
  const int n = 100;
  for (int k = 0; k < n; ++k) {
    integrate_velocities(m, s, h);
    integrate_positions(m, s, delta, h, Rotation::Normalize);
  }
  CHECK_NEAR(s.body_x[0].y, -9.81 * h * h * n * (n + 1) / 2.0, 1e-12);
  CHECK_NEAR(s.body_v[0].y, -9.81 * h * n, 1e-12);
  CHECK_NEAR(delta[0].dx.y, s.body_x[0].y, 1e-15);
}

// 2D `normalize` turns by atan(h ω) per step and keeps |q| = 1 and the unwrapped angle.
TEST(planar_rotation_turns_by_atan_h_omega) {
  Model<2> m;
  State<2> s;
  one_body(m, s);
  m.body_inertia = {1.0};
  m.body_inv_inertia = {1.0};
  s.body_w[0] = 50.0;
  std::vector<BodyDelta<2>> delta(1);
  const double h = 0.01;
  for (int k = 0; k < 1000; ++k) integrate_positions(m, s, delta, h, Rotation::Normalize);
  CHECK_NEAR(s.body_angle[0], 1000 * std::atan(h * 50.0), 1e-9);
  CHECK_NEAR(std::hypot(s.body_q[0].c, s.body_q[0].s), 1.0, 1e-15);
  CHECK_NEAR(std::atan2(s.body_q[0].s, s.body_q[0].c), std::remainder(s.body_angle[0], 2 * M_PI), 1e-9);
}

// A torque-free asymmetric body in 3D keeps its angular momentum L exactly (L is the
// state), while ω = R I⁻¹ Rᵀ L wanders; the same integrator that steps the plane.
TEST(free_body_in_3d_keeps_angular_momentum) {
  Model<3> m;
  State<3> s;
  one_body(m, s);
  const Sym3 inertia{1.0, 2.0, 3.0, 0.0, 0.0, 0.0};  // kg·m², principal axes
  m.body_inertia = {inertia};
  m.body_inv_inertia = {Sym3{1.0, 0.5, 1.0 / 3.0, 0.0, 0.0, 0.0}};
  s.body_l[0] = {0.1, 4.0, 0.2};  // near the intermediate axis: it tumbles
  s.body_w[0] = Dim<3>::apply_inv_inertia(m.body_inv_inertia[0], s.body_q[0], s.body_l[0]);
  const Vec3 l0 = s.body_l[0];
  const Vec3 w0 = s.body_w[0];
  std::vector<BodyDelta<3>> delta(1);
  const double h = 1e-3;
  double w_change = 0.0;
  for (int k = 0; k < 20000; ++k) {  // 20 s: past the first flip
    integrate_velocities(m, s, h);
    integrate_positions(m, s, delta, h, Rotation::Exact);
    w_change = std::fmax(w_change, length(s.body_w[0] - w0));
  }
  CHECK(s.body_l[0].x == l0.x && s.body_l[0].y == l0.y && s.body_l[0].z == l0.z);
  const Quat q = s.body_q[0];
  CHECK_NEAR(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z, 1.0, 1e-14);
  CHECK(w_change > 1.0);  // ω moved (the flip of the intermediate axis), L did not
  // ω stays consistent with L through the body's current orientation
  const Vec3 w = Dim<3>::apply_inv_inertia(m.body_inv_inertia[0], q, l0);
  CHECK_NEAR(length(w - s.body_w[0]), 0.0, 1e-14);
}

// 3D `normalize` (q <- normalize(q + h/2 ω q)) and `exact` agree to first order for a
// steady spin about a principal axis, and `exact` turns by h ω exactly.
TEST(spin_about_a_principal_axis_in_3d) {
  Model<3> m;
  State<3> s;
  one_body(m, s);
  m.body_inertia = {Sym3{2.0, 2.0, 2.0, 0, 0, 0}};
  m.body_inv_inertia = {Sym3{0.5, 0.5, 0.5, 0, 0, 0}};
  s.body_l[0] = {0.0, 0.0, 2.0};  // ω = 1 rad/s about z
  s.body_w[0] = {0.0, 0.0, 1.0};
  std::vector<BodyDelta<3>> delta(1);
  for (int k = 0; k < 1000; ++k) integrate_positions(m, s, delta, 1e-3, Rotation::Exact);
  const Quat q = s.body_q[0];
  CHECK_NEAR(2.0 * std::atan2(q.z, q.w), 1.0, 1e-12);  // turned by 1 rad about z
  CHECK_NEAR(delta[0].dq.z, q.z, 1e-12);  // the delta is not renormalised: round-off of 1000 products
}

namespace {

// A torque-free box of 0.2 × 0.1 × 0.05 m (the tumbling brick, 1 kg) whose
// principal axes are turned from its body axes by a fixed rotation (so that the split
// update's principal frame is really used), spun near its intermediate axis.
struct Tumbler {
  Model<3> m;
  State<3> s;
  Vec3 moments;
  // ω = (tilt, spin, 0) in principal axes (a tilt off the intermediate axis about the
  // minor one: (t, spin, t) would lie on the separatrix for this box)
  Tumbler(double spin, double tilt) {
    one_body(m, s);
    const double a = 0.2, b = 0.1, c = 0.05, mass = 1.0;
    moments = {mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12, mass * (a * a + b * b) / 12};
    // principal → body: 0.4 rad about (1, 2, 3)/|.|
    const double n = std::sqrt(14.0), half = 0.2;
    const Quat axes{std::cos(half), std::sin(half) / n, 2 * std::sin(half) / n, 3 * std::sin(half) / n};
    // I_b = P diag P^T, its inverse alike
    auto tensor = [&](Vec3 d) {
      Sym3 diag{d.x, d.y, d.z, 0, 0, 0};
      return world_tensor(axes, diag);
    };
    m.body_inertia = {tensor(moments)};
    m.body_inv_inertia = {tensor({1 / moments.x, 1 / moments.y, 1 / moments.z})};
    m.body_axes = {axes};
    m.body_moments = {moments};
    // ω about the intermediate principal axis, with a small tilt off it
    const Vec3 w_principal{tilt, spin, 0.0};
    const Vec3 l_principal{moments.x * w_principal.x, moments.y * w_principal.y, moments.z * w_principal.z};
    s.body_q[0] = Quat{1, 0, 0, 0};
    s.body_l[0] = rotate(axes, l_principal);  // q = identity: world = body frame
    s.body_w[0] = Dim<3>::apply_inv_inertia(m.body_inv_inertia[0], s.body_q[0], s.body_l[0]);
  }
  double energy() const { return 0.5 * dot(s.body_w[0], s.body_l[0]); }
  // ω along the intermediate principal axis, in principal coordinates
  double w2() const {
    const Quat p = mul(s.body_q[0], m.body_axes[0]);
    return inv_rotate(p, s.body_w[0]).y;
  }
};

// The complete elliptic integral of the first kind K(k), given k' ² = 1 - k², by the
// arithmetic-geometric mean.
double elliptic_k(double kc2) {
  double a = 1.0, b = std::sqrt(kc2);
  for (int i = 0; i < 40; ++i) {
    const double an = 0.5 * (a + b);
    b = std::sqrt(a * b);
    a = an;
  }
  return M_PI / (2.0 * a);
}

// Time (s) between two flips of the intermediate axis of a torque-free body, closed form
// (Landau & Lifshitz §37): half the period T = 4 K(k) / ν of the polhode.
double flip_interval(Vec3 i, double energy, double l2) {
  double i1 = i.x, i2 = i.y, i3 = i.z;
  if (l2 < 2 * energy * i2) std::swap(i1, i3);  // the polhode circles the other axis
  const double a = (i3 - i2) * (l2 - 2 * energy * i1);
  const double nu = std::sqrt(std::fabs(a / (i1 * i2 * i3)));
  // 1 - k², in the form that does not cancel near the separatrix
  const double kc2 = (i3 - i1) * (l2 - 2 * energy * i2) / a;
  return 2.0 * elliptic_k(kc2) / nu;
}

}  // namespace

// `split`: world L unchanged to the bit, |q| = 1, and the energy error bounded: over 10⁶
// steps of 1 ms its largest value is at most twice its largest over the first 10⁴ (three
// flips of the intermediate axis, 2.94 s apart; the notes' `normalize` update gains energy
// every step instead).
TEST(split_rotation_keeps_l_exactly_and_its_energy_error_bounded) {
  Tumbler t(5.0, 0.2);
  const Vec3 l0 = t.s.body_l[0];
  const double e0 = t.energy();
  std::vector<BodyDelta<3>> delta(1);
  double early = 0.0, late = 0.0;
  for (int k = 1; k <= 1000000; ++k) {
    integrate_positions(t.m, t.s, delta, 1e-3, Rotation::Split);
    const double err = std::fabs(t.energy() - e0);
    (k <= 10000 ? early : late) = std::max(k <= 10000 ? early : late, err);
  }
  CHECK(t.s.body_l[0].x == l0.x && t.s.body_l[0].y == l0.y && t.s.body_l[0].z == l0.z);
  const Quat q = t.s.body_q[0];
  CHECK_NEAR(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z, 1.0, 1e-12);
  CHECK(early > 0.0);
  std::printf("     energy error: first 10^4 steps %.3g J, all 10^6 %.3g J\n", early, std::max(early, late));
  CHECK(late <= 2.0 * early);
  // and `normalize` on the same body drifts: after 2×10⁴ steps its error is far above
  Tumbler n(5.0, 0.2);
  for (int k = 0; k < 20000; ++k) integrate_positions(n.m, n.s, delta, 1e-3, Rotation::Normalize);
  CHECK(n.energy() - e0 > 10.0 * late);
}

// The flips of the intermediate axis come at the closed-form interval (0.1%) with `split`.
TEST(split_rotation_flips_at_the_closed_form_interval) {
  Tumbler t(5.0, 0.2);
  const Vec3 l = t.s.body_l[0];
  const double expected = flip_interval(t.moments, t.energy(), dot(l, l));
  std::vector<BodyDelta<3>> delta(1);
  const double h = 1e-3;
  std::vector<double> crossings;  // times where ω₂ changes sign
  double prev = t.w2();
  for (int k = 1; k <= 60000 && crossings.size() < 8; ++k) {
    integrate_positions(t.m, t.s, delta, h, Rotation::Split);
    const double now = t.w2();
    if ((prev > 0) != (now > 0)) {
      // linear interpolation of the crossing inside the step
      crossings.push_back(h * (k - 1 + prev / (prev - now)));
    }
    prev = now;
  }
  CHECK(crossings.size() >= 3);
  const double measured = (crossings.back() - crossings.front()) / (crossings.size() - 1);
  std::printf("     flip interval %.6f s, closed form %.6f s\n", measured, expected);
  CHECK_NEAR(measured / expected, 1.0, 1e-3);
}

// 3D `normalize` with the world tensors kept (the contact path) moves dynamic bodies in
// lanes (integrate.cpp, move_3d), diagonal body tensors or not: a body's bits must not
// depend on the bodies beside it
// or on how the bodies are split into parts (threads), and must be the one-body update's
// to rounding.
// Eleven bodies for the lanes: body 0 static, body 9 kinematic (runs 4..7 in whole runs,
// the rest picked out); every third tensor not diagonal; principal moments for `split`
// of every kind (three equal, two equal, all different) and spins whose turns take each
// of its sine series and the library's.
struct LaneBodies {
  static constexpr int n = 11;
  Model<3> m;
  State<3> s;
  // fast: |L| from 1 to 2000 kg·m²/s (turns of 1e-3 to 1 rad a substep), else 1 to 3
  explicit LaneBodies(bool fast) {
    m.body_type.assign(n, BodyType::Dynamic);
    m.body_type[0] = BodyType::Static;
    m.body_type[9] = BodyType::Kinematic;
    m.body_inv_inertia.resize(n);
    m.body_axes.resize(n);
    m.body_moments.resize(n);
    s.body_x.resize(n);
    s.body_q.resize(n);
    s.body_v.resize(n);
    s.body_w.resize(n);
    s.body_l.resize(n);
    for (int i = 0; i < n; ++i) {
      const double t = 0.37 * i + 0.1;
      // every third body's tensor not diagonal (a hull's, about axes not its principal
      // ones); each positive definite (diagonally dominant)
      const double off = i % 3 == 1 ? 0.3 : 0.0;
      m.body_inv_inertia[i] = {1.0 + t, 2.0 + 0.5 * t, 0.7 + t * t, off, -0.5 * off, 0.2 * off};
      m.body_axes[i] = normalize(Quat{1.0, 0.1 * t, 0.2, -0.3 * t});
      const double base = 0.5 + 0.1 * t;  // kg·m²
      m.body_moments[i] = i % 3 == 0   ? Vec3{base, base, base}
                          : i % 3 == 1 ? Vec3{0.2 * base, base, base}
                                       : Vec3{0.3 * base, base, 1.7 * base};
      s.body_x[i] = {std::sin(3 * t), 2 * t, -t};
      s.body_v[i] = {std::cos(t), -9.0 * t, 0.25};
      s.body_q[i] = normalize(Quat{1.0, 0.3 * t, -0.2, std::sin(t)});
      const double spin = fast ? std::pow(10.0, 0.33 * i) : 1.0;
      s.body_l[i] = spin * Vec3{0.5 - t, 3.0 * std::cos(2 * t), t * t};
      s.body_w[i] = world_tensor(s.body_q[i], m.body_inv_inertia[i]) * s.body_l[i];
    }
  }
  struct Run {
    State<3> s;
    std::vector<BodyDelta<3>> d;
    std::vector<Sym3> w;
  };
  // four substeps of h, each split into the parts
  Run run(Rotation rotation, const std::vector<Span>& parts, double h) const {
    Run r{s, std::vector<BodyDelta<3>>(n), std::vector<Sym3>(n)};
    for (int sub = 0; sub < 4; ++sub)
      for (const Span& p : parts) integrate_positions(m, r.s, r.d, h, rotation, p, r.w.data());
    return r;
  }
  // the same bits whole, one body a part, and in two uneven parts
  void check_parts(Rotation rotation, double h) const {
    std::vector<Span> singles;
    for (int i = 0; i < n; ++i) singles.push_back({i, i + 1});
    const Run whole = run(rotation, {{0, n}}, h);
    const Run ones = run(rotation, singles, h);
    const Run halves = run(rotation, {{0, 6}, {6, n}}, h);
    auto same = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof a) == 0; };
    for (const Run* r : {&ones, &halves}) {
      for (int i = 0; i < n; ++i) {
        CHECK(same(whole.s.body_x[i], r->s.body_x[i]));
        CHECK(same(whole.s.body_q[i], r->s.body_q[i]));
        CHECK(same(whole.s.body_w[i], r->s.body_w[i]));
        CHECK(same(whole.w[i], r->w[i]));
        CHECK(same(whole.d[i].dx, r->d[i].dx));
        CHECK(same(whole.d[i].dq, r->d[i].dq));
      }
    }
  }
};

TEST(bodies_moved_in_lanes_get_the_same_bits_however_split) {
  const LaneBodies bodies(false);
  const int n = LaneBodies::n;
  const Model<3>& m = bodies.m;
  const State<3>& start = bodies.s;
  const double h = 1.0 / 960.0;
  bodies.check_parts(Rotation::Normalize, h);
  const auto whole = bodies.run(Rotation::Normalize, {{0, n}}, h);
  // the one-body update (turn() for `normalize`; a kinematic body turns by exactly h ω),
  // written out here: to rounding
  for (int i = 1; i < n; ++i) {
    Vec3 x = start.body_x[i], w = start.body_w[i];
    Quat q = start.body_q[i], dq{};
    for (int sub = 0; sub < 4; ++sub) {
      x += h * start.body_v[i];
      Quat nq;
      if (m.is_dynamic(i)) {
        const Quat d = mul(Quat{0.0, w.x, w.y, w.z}, q);
        nq = {q.w + 0.5 * h * d.w, q.x + 0.5 * h * d.x, q.y + 0.5 * h * d.y, q.z + 0.5 * h * d.z};
      } else {
        const double half = 0.5 * h * length(w), k = std::sin(half) / length(w);
        nq = mul(Quat{std::cos(half), k * w.x, k * w.y, k * w.z}, q);
      }
      const Quat r = mul(normalize(nq), Quat{q.w, -q.x, -q.y, -q.z});
      q = normalize(nq);
      dq = mul(r, dq);
      if (m.is_dynamic(i)) w = world_tensor(q, m.body_inv_inertia[i]) * start.body_l[i];
    }
    // (1e-14 m, 1e-15 for unit quaternions, 1e-14 relative for ω: a few roundings of
    // values of order 1 to 10)
    CHECK_NEAR(length(whole.s.body_x[i] - x), 0.0, 1e-14);
    CHECK_NEAR(whole.s.body_q[i].w, q.w, 1e-15);
    CHECK_NEAR(whole.s.body_q[i].x, q.x, 1e-15);
    CHECK_NEAR(whole.s.body_q[i].y, q.y, 1e-15);
    CHECK_NEAR(whole.s.body_q[i].z, q.z, 1e-15);
    CHECK_NEAR(length(whole.s.body_w[i] - w), 0.0, 1e-14 * length(w));
    CHECK_NEAR(whole.d[i].dq.w, dq.w, 1e-15);
    CHECK_NEAR(whole.d[i].dq.x, dq.x, 1e-15);
    CHECK_NEAR(whole.d[i].dq.y, dq.y, 1e-15);
    CHECK_NEAR(whole.d[i].dq.z, dq.z, 1e-15);
  }
}

// `split` in lanes too: a body's bits are its own, whatever its lane-mates (their axis
// turns left out where none of the lanes has one, each body's sine series its own
// angle's), and the one-body update's (the same operations on a double) to the bit.
TEST(split_bodies_in_lanes_get_the_same_bits_however_split_and_alone) {
  const LaneBodies bodies(true);
  const double h = 1.0 / 960.0;
  bodies.check_parts(Rotation::Split, h);
  const auto whole = bodies.run(Rotation::Split, {{0, LaneBodies::n}}, h);
  // the path without world tensors (no contacts) turns one body at a time
  State<3> alone = bodies.s;
  std::vector<BodyDelta<3>> d(LaneBodies::n);
  for (int sub = 0; sub < 4; ++sub) integrate_positions(bodies.m, alone, d, h, Rotation::Split);
  for (int i = 1; i < LaneBodies::n; ++i) {
    if (i == 9) continue;  // (kinematic: turned by exactly h ω on either path)
    CHECK(std::memcmp(&whole.s.body_q[i], &alone.body_q[i], sizeof(Quat)) == 0);
  }
}

// 2D without forces the velocities of four dynamic bodies next to one another are updated
// in lanes, the others one by one: the same bits either way. Nine bodies, then the same
// nine with a static body second (the lanes fall on other bodies), damped both ways.
TEST(velocities_in_lanes_are_the_one_by_one_velocities_to_the_bit) {
  auto make = [](bool static_second, Model<2>& m, State<2>& s) {
    const int n = static_second ? 10 : 9;
    m = Model<2>{};
    s = State<2>{};
    m.gravity = {0.3, -9.81};
    m.linear_damping = 0.3;
    m.angular_damping = 0.7;
    for (int k = 0, i = 0; k < n; ++k) {
      const bool fixed = static_second && k == 1;
      m.body_type.push_back(fixed ? BodyType::Static : BodyType::Dynamic);
      m.body_inv_mass.push_back(fixed ? 0.0 : 1.0 / (1.0 + i));
      m.body_inv_inertia.push_back(fixed ? 0.0 : 2.0 / (1.0 + i));
      s.body_v.push_back(fixed ? Vec2{} : Vec2{0.1 * i - 0.35, 1.0 / (3.0 + i)});
      s.body_w.push_back(fixed ? 0.0 : 0.7 - 0.2 * i);
      if (!fixed) ++i;
    }
    const std::size_t size = m.body_type.size();
    m.body_mass.resize(size), m.body_inertia.resize(size), m.body_com.resize(size);
    m.body_force.resize(size), m.body_force_arm.resize(size), m.body_torque.resize(size);
    s.body_x.resize(size), s.body_q.resize(size), s.body_angle.resize(size);
  };
  Model<2> ma, mb;
  State<2> sa, sb;
  make(false, ma, sa);
  make(true, mb, sb);
  for (int step = 0; step < 3; ++step) {
    integrate_velocities(ma, sa, 1.0 / 240.0);
    integrate_velocities(mb, sb, 1.0 / 240.0);
  }
  for (int i = 0; i < 9; ++i) {
    const int j = i == 0 ? 0 : i + 1;  // (body i of the first is body j of the second)
    CHECK(std::memcmp(&sa.body_v[i], &sb.body_v[j], sizeof(Vec2)) == 0);
    CHECK(std::memcmp(&sa.body_w[i], &sb.body_w[j], sizeof(double)) == 0);
    CHECK(sa.body_v[i].x != 0.1 * i - 0.35);  // (they moved)
  }
  CHECK(sb.body_v[1].x == 0.0 && sb.body_v[1].y == 0.0 && sb.body_w[1] == 0.0);  // the static
}

RBSIM_TEST_MAIN
