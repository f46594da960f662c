// collide/continuous.cpp: a body that went further in the step than its contacts reached
// is put back where it met the static shape it went through; a body whose motion its
// contacts covered, one stopped at the wall, and one sliding along the floor it stood on
// are left.
#include <algorithm>
#include <cmath>
#include <vector>

#include "check.hpp"
#include "scene_builder.hpp"
#include "scene_builder3d.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::SceneBuilder3;

namespace {

constexpr double DT = 1.0 / 60.0;  // s

// The step's end as the passes would leave it: body i moved by dx (m) and turned by
// `turn` (rad, 2D) from the pose the contacts were found at, its velocity v now (m/s).
void moved(World<2>& w, int i, Vec2 dx, double turn, Vec2 v) {
  w.state.body_x[i] += dx;
  w.state.body_angle[i] += turn;
  const Rot2 r{std::cos(turn), std::sin(turn)};
  w.state.body_q[i] = mul(r, w.state.body_q[i]);
  w.state.body_v[i] = v;
  w.contacts.body_delta[i] = {dx, r};
}

// The world's contacts found with every body at rest, then body i moved by dx (m) within
// the step at v (m/s) now, and swept: how many were put back.
std::int64_t sent(World<2>& w, int i, Vec2 dx, Vec2 v) {
  rbsim::test::collide(w);
  const std::vector<Vec2> v0 = w.state.body_v;
  const std::vector<double> w0 = w.state.body_w;
  moved(w, i, dx, 0.0, v);
  return sweep_fast_bodies(w.model, w.state, w.contacts, w.grid, w.continuous_index, v0, w0, DT,
                           MixRule::Max, 1.0);
}

// 3D: the world's contacts found with every body at rest, then body i moved by dx (m)
// along x within the step at v (m/s) now, and swept: how many were put back.
std::int64_t sent_along_x(World<3>& w, int i, double dx, double v) {
  rbsim::test::collide3(w);
  for (auto& d : w.contacts.body_delta) d = {};
  const std::vector<Vec3> v0 = w.state.body_v, w0 = w.state.body_w;
  w.state.body_x[i].x += dx;
  w.state.body_v[i] = {v, 0.0, 0.0};
  w.contacts.body_delta[i].dx = {dx, 0.0, 0.0};
  return sweep_fast_bodies(w.model, w.state, w.contacts, w.grid, w.continuous_index, v0, w0, DT,
                           MixRule::Max, 1.0);
}

// A ball of 5 cm, 0.3 m in front of a static wall 10 cm thick (x 0.3 .. 0.4), at rest when
// its contacts were found: a world after collide, and the ball.
struct Wall2 {
  SceneBuilder s;
  int ball;
  World<2>* w;
  std::vector<Vec2> v0;
  std::vector<double> w0;
  Wall2() {
    s.world.model.gravity = {0.0, 0.0};
    s.box({0.35, 0.0}, 0.05, 0.5, 0.0);
    ball = s.circle({0.0, 0.0}, 0.05, 1.0);
    w = &s.finish();
    rbsim::test::collide(*w);
    v0 = w->state.body_v;
    w0 = w->state.body_w;
  }
  std::int64_t sweep() {
    return sweep_fast_bodies(w->model, w->state, w->contacts, w->grid, w->continuous_index, v0, w0,
                             DT, MixRule::Max, 1.0);
  }
};

}  // namespace

// Struck within the step to 60 m/s, it went 1 m, through the wall: put back touching it,
// turned by the same share of its turn, its velocity and spin kept.
TEST(a_ball_struck_through_a_wall_is_put_back_at_it) {
  Wall2 t;
  moved(*t.w, t.ball, {1.0, 0.0}, 0.4, {60.0, 0.0});
  t.w->state.body_w[t.ball] = 24.0;
  CHECK(t.sweep() == 1);
  const double x = t.w->state.body_x[t.ball].x;
  CHECK_NEAR(x, 0.25, 1e-6);  // (the search stops within its tolerance of touching)
  CHECK_NEAR(t.w->state.body_angle[t.ball], 0.4 * x, 1e-9);
  CHECK_NEAR(t.w->state.body_q[t.ball].s, std::sin(0.4 * x), 1e-9);
  CHECK_NEAR(t.w->contacts.body_delta[t.ball].dx.x, x, 1e-15);
  CHECK(t.w->state.body_v[t.ball].x == 60.0 && t.w->state.body_w[t.ball] == 24.0);
}

// Touching the wall when its contacts were found, and sent through it within the step
// (struck, or turned into it by the push that stopped its corner): put back where it
// started, its approach there is taken as one collision, reversed by the pair's
// restitution (it bounces off the wall at e = 1, stops at e = 0). Kept, the next step
// began from the same pose with the same approach, and a box by a floor's corner was put
// back step after step while gravity built up its speed.
TEST(a_body_put_back_where_it_started_strikes_the_wall_there) {
  for (const double e : {0.0, 1.0}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    s.box({0.35, 0.0}, 0.05, 0.5, 0.0, {0.6, e});
    const int ball = s.circle({0.25, 0.0}, 0.05, 1.0, {0.6, e});
    World<2>& w = s.finish();
    CHECK(sent(w, ball, {0.5, 0.0}, {30.0, 0.0}) == 1);
    CHECK_NEAR(w.state.body_x[ball].x, 0.25, 1e-6);
    // (the ball's point meets the wall on the line of centres: no spin)
    CHECK_NEAR(w.state.body_v[ball].x, -30.0 * e, 1e-9);
    CHECK(std::fabs(w.state.body_w[ball]) < 1e-9);
  }
}

// Moving at 60 m/s when the contacts were found, the wall was within its reach (the
// solver's speculative contact holds it): the sweep leaves it.
TEST(a_body_whose_contacts_covered_its_motion_is_left) {
  Wall2 t;
  t.v0[t.ball] = {60.0, 0.0};
  moved(*t.w, t.ball, {1.0, 0.0}, 0.0, {60.0, 0.0});
  CHECK(t.sweep() == 0);
  CHECK(t.w->state.body_x[t.ball].x == 1.0);
}

// Stopped at the wall by the solver (it went on into nothing), or gone on into it by less
// than half its radius (push-out brings it back): left, to the bit.
TEST(a_body_stopped_at_the_wall_or_moved_a_little_is_left) {
  Wall2 t;
  moved(*t.w, t.ball, {0.25, 0.0}, 0.0, {0.0, 0.0});
  CHECK(t.sweep() == 0);
  CHECK(t.w->state.body_x[t.ball].x == 0.25);
  Wall2 u;
  const double inside = 0.25 + 0.02;  // 2 cm into the wall, of a radius of 5 cm
  moved(*u.w, u.ball, {inside, 0.0}, 0.0, {0.0, 0.0});
  CHECK(u.sweep() == 0);
  CHECK(u.w->state.body_x[u.ball].x == inside);
}

// A box standing on the ground, struck within the step to slide 1 m along it: the ground
// it started on is not in its way.
TEST(a_body_sliding_along_the_floor_it_stood_on_is_left) {
  SceneBuilder s;
  s.ground();
  const int box = s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  CHECK(sent(w, box, {1.0, 0.0}, {60.0, 0.0}) == 0);
  CHECK(w.state.body_x[box].x == 1.0);
}

// In space: a sphere struck through a box wall is put back touching it, and a box's inner
// size is its least half extent.
TEST(a_sphere_struck_through_a_box_wall_is_put_back_at_it) {
  SceneBuilder3 s;
  s.world.model.gravity = {};
  s.box({0.35, 0.0, 0.0}, {0.05, 0.5, 0.5}, 0.0);
  const int ball = s.sphere({0.0, 0.0, 0.0}, 0.05, 1.0);
  const int brick = s.box({0.0, 2.0, 0.0}, {0.1, 0.2, 0.3}, 1.0);
  World<3>& w = s.finish();
  CHECK(sent_along_x(w, ball, 1.0, 60.0) == 1);
  CHECK_NEAR(w.state.body_x[ball].x, 0.25, 1e-6);
  CHECK(w.state.body_v[ball].x == 60.0);
  CHECK_NEAR(w.continuous_index.inner[ball], 0.05, 1e-15);
  CHECK_NEAR(w.continuous_index.inner[brick], 0.1, 1e-15);
  CHECK(w.continuous_index.static_shapes.size() == 1 && w.continuous_index.static_shapes[0] == 0);
}

// In space as in the plane: a box touching a wall by a corner, sent through it, is put
// back where it started and struck back there; the impulse at the corner, off the line
// through its centre, also turns it, and at e = 1 its kinetic energy stays what it was.
TEST(a_box_put_back_where_it_started_strikes_the_wall_there_in_space) {
  SceneBuilder3 s;
  s.world.model.gravity = {};
  s.box({0.35, 0.0, 0.0}, {0.05, 0.5, 0.5}, 0.0, {0.6, 1.0});
  const double h = 0.1;  // m: the box's half extent
  const double half = 0.3;  // rad: half its turn about (0, 1, 1) / √2
  const Quat q{std::cos(half), 0.0, std::sin(half) / std::sqrt(2.0), std::sin(half) / std::sqrt(2.0)};
  double lead = 0.0;  // m: how far its leading corner lies ahead of its centre along x
  for (const double sx : {-h, h})
    for (const double sy : {-h, h})
      for (const double sz : {-h, h}) lead = std::max(lead, rotate(q, Vec3{sx, sy, sz}).x);
  const int box = s.box({0.3 - lead, 0.0, 0.0}, {h, h, h}, 2.0, {0.6, 1.0}, q);
  World<3>& w = s.finish();
  CHECK(sent_along_x(w, box, 0.5, 30.0) == 1);
  CHECK_NEAR(w.state.body_x[box].x, 0.3 - lead, 1e-6);
  const Vec3 v = w.state.body_v[box], L = w.state.body_l[box], om = w.state.body_w[box];
  CHECK(v.x < 0.0);            // away from the wall
  CHECK(length(om) > 1.0);     // turned by an impulse off its centre's line
  const double kinetic = 0.5 * 2.0 * dot(v, v) + 0.5 * dot(om, L);  // J
  CHECK_NEAR(kinetic, 0.5 * 2.0 * 30.0 * 30.0, 1e-9 * 900.0);  // (round-off of a few terms)
}

RBSIM_TEST_MAIN
