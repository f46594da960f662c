// step.cpp: whole worlds built in C++ and stepped.
#include <algorithm>
#include <cmath>
#include <limits>

#include "check.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::same_bits;

namespace {

// A few boxes and balls falling onto a ground and onto each other: contacts, friction,
// bounces and the shock pass all take part.
void pile(SceneBuilder& s) {
  s.ground(-5.0, 5.0);
  for (int i = 0; i < 4; ++i) {
    s.box({-1.0 + 0.55 * i, 0.5 + 1.05 * i}, 0.25, 0.25, 1.0 + i, {}, 0.1 * i);
    s.circle({0.8 - 0.3 * i, 1.0 + 0.9 * i}, 0.2, 0.5, {0.4, 0.5}, {0.3, 0.0}, 1.0);
  }
}

}  // namespace

// A ball dropped from 1 m onto a static box stops on its top face (e = 0): after 2 s it
// is at rest, at the surface to within the soft contact's sag.
TEST(ball_dropped_on_static_box_comes_to_rest) {
  SceneBuilder s;
  s.box({0, -0.5}, 2.0, 0.5, 0.0);
  const int ball = s.circle({0.1, 1.25}, 0.25, 1.0);
  World<2>& w = s.finish();
  std::int64_t taken = 0, bad = -1;
  CHECK(w.advance(120, &taken, &bad) == Status::Ok);
  CHECK(taken == 120);
  CHECK(length(w.state.body_v[ball]) < 1e-6);            // m/s: at rest
  CHECK(std::fabs(w.state.body_w[ball]) < 1e-6);         // rad/s
  CHECK_NEAR(w.state.body_x[ball].y, 0.25, 1e-3);        // m: sag of a 1 kg ball, < 1 mm
  CHECK_NEAR(w.state.body_x[ball].x, 0.1, 1e-6);         // a straight drop: no drift
  CHECK(w.contact_count() == 1);
}

// A body falling freely (no contacts possible) follows symplectic Euler's sum over the
// substeps: y = y0 - g h² n (n + 1) / 2 after n substeps of h.
TEST(lone_body_falls_by_the_symplectic_euler_sum) {
  SceneBuilder s;
  const int ball = s.circle({0, 10}, 0.1, 1.0);
  World<2>& w = s.finish(0.01, 2);
  CHECK(!w.model.has_shapes);  // one shape: the contact stages are skipped
  for (int k = 0; k < 50; ++k) CHECK(w.step());
  const double h = 0.005;
  const int n = 100;
  CHECK_NEAR(w.state.body_x[ball].y, 10.0 - 9.81 * h * h * n * (n + 1) / 2.0, 1e-12);
}

// Determinism: two worlds built and stepped alike give the same state to the bit, step
// after step, through contacts, bounces and a growing store.
TEST(two_worlds_stepped_alike_are_bit_identical) {
  SceneBuilder s1, s2;
  pile(s1);
  pile(s2);
  World<2>& w1 = s1.finish();
  World<2>& w2 = s2.finish();
  bool same = true;
  for (int k = 0; k < 240; ++k) {
    std::int64_t t1 = 0, t2 = 0, bad = -1;
    w1.advance(1, &t1, &bad);
    w2.advance(1, &t2, &bad);
    same = same && rbsim::test::same_bits(w1.state, w2.state);
  }
  CHECK(same);
  CHECK(w1.contact_count() > 4);  // the pile has settled onto the ground and each other
}

// A 100 kg box on a 0.01 kg box on the ground (mass ratio 10⁴): after 5 s at rest the
// light box is not crushed, neither contact overlaps by 1% of the 1 m boxes (the soft
// contacts, whose stiffness follows the light box's mass, let the heavy one sink in by
// 33 cm), and neither box moved sideways.
TEST(heavy_box_on_a_far_lighter_one_does_not_sink_in) {
  SceneBuilder s;
  s.ground();
  const int light = s.box({0.0, 0.5}, 0.5, 0.5, 0.01);
  const int heavy = s.box({0.0, 1.5}, 0.5, 0.5, 100.0);
  World<2>& w = s.finish();
  std::int64_t taken = 0, bad = -1;
  CHECK(w.advance(300, &taken, &bad) == Status::Ok);
  const double light_y = w.state.body_x[light].y, heavy_y = w.state.body_x[heavy].y;
  CHECK(0.5 - light_y < 0.01);                 // m: into the ground
  CHECK((light_y + 0.5) - (heavy_y - 0.5) < 0.01);  // m: the heavy box into the light one
  CHECK(std::fabs(w.state.body_x[light].x) < 1e-9 && std::fabs(w.state.body_x[heavy].x) < 1e-9);
  CHECK(length(w.state.body_v[heavy]) < 1e-3);  // m/s: at rest
}

// 400 balls in one spot: every one of their 79,800 pairs overlaps, above the pair limit
// of 400 shapes (32 x 400 + 65,536 = 78,336). advance takes no step and says so, with the
// pairs it found; spread out, the same world steps again.
TEST(a_step_with_more_pairs_than_the_limit_is_not_taken) {
  SceneBuilder s;
  const int n = 400;
  for (int i = 0; i < n; ++i) s.circle({1e-3 * (i % 20), 1e-3 * (i / 20)}, 0.5, 1.0);
  World<2>& w = s.finish();
  CHECK(w.pair_limit() == 32 * n + 65536);
  const State<2> before = w.state;
  std::int64_t taken = -1, bad = 0;
  CHECK(w.advance(5, &taken, &bad) == Status::TooManyPairs);
  CHECK(taken == 0 && bad == -1);
  CHECK(w.pairs_wanted == n * (n - 1) / 2);
  CHECK(w.step_index == 0);
  CHECK(same_bits(w.state, before));  // the refused step left the state as it was
  for (int i = 0; i < n; ++i) w.state.body_x[i] = {2.0 * (i % 20), 2.0 * (i / 20)};
  CHECK(w.advance(5, &taken, &bad) == Status::Ok);
  CHECK(taken == 5);
}

// The work bound: pairs x substeps x iterations at most PAIR_WORK_MAX.
TEST(the_pair_limit_falls_with_the_work_of_a_pair) {
  SceneBuilder s;
  s.ground();
  s.circle({0, 1}, 0.5, 1.0);
  World<2>& w = s.finish(1.0 / 60.0, 1000);
  w.config.iterations = 4;
  CHECK(w.pair_limit() == 2000);  // 8e6 / (1000 x 4)
}

// A step that may be long is asked inside (World::interrupt): a stop there ends advance
// with Interrupted and a torn world, which refuses to step on; a short step is only asked
// between steps (a stop there leaves the state whole).
TEST(a_long_step_is_stopped_inside_and_leaves_a_torn_world) {
  SceneBuilder s;
  s.ground();
  for (int i = 0; i < 10; ++i) s.circle({0, 0.5 + i}, 0.5, 1.0);
  World<2>& w = s.finish();
  std::int64_t taken = -1, bad = 0;
  int asked = 0;
  w.interrupt = [&] { return ++asked >= 1000000; };  // asks counted, none stops
  CHECK(w.advance(3, &taken, &bad) == Status::Ok && taken == 3);
  CHECK(asked == 0);  // short steps (the first one's work bound too): never asked inside
  w.last_step_seconds = 10.0;  // as after a long step: the next one is asked inside
  asked = 0;
  w.advance(1, &taken, &bad);
  // after finding the pairs, after preparing the contacts, after collide, between substeps
  CHECK(asked == 3 + w.config.substeps - 1);
  w.last_step_seconds = 10.0;
  const std::int64_t at = w.step_index;
  w.interrupt = [&] { return true; };
  CHECK(w.advance(5, &taken, &bad) == Status::Interrupted);
  CHECK(taken == 0 && bad == -1 && w.torn && w.step_index == at);
  CHECK(w.advance(1, &taken, &bad) == Status::Torn && taken == 0);
}

// A store that grows for a step asks interrupt while it is made: a stop leaves it as it
// was, and the world steps on from the same state as an uninterrupted one.
TEST(a_grow_stopped_midway_leaves_the_store_as_it_was) {
  auto build = [] {
    SceneBuilder s;
    s.ground();
    for (int i = 0; i < 200; ++i) s.circle({0.9 * (i % 20), 0.5 + 0.9 * (i / 20)}, 0.5, 1.0);
    return s;
  };
  SceneBuilder sa = build(), sb = build();
  World<2>& a = sa.finish();
  World<2>& b = sb.finish();
  const std::int64_t room = a.contacts.capacity();
  std::int64_t taken = -1, bad = 0;
  int asked = 0;
  a.interrupt = [&] { return ++asked == 3; };  // the third ask: inside the store's making
  CHECK(a.grow(4 * room, true) == false);
  CHECK(asked == 3 && a.contacts.capacity() == room && !a.torn);
  a.interrupt = nullptr;
  CHECK(a.advance(20, &taken, &bad) == Status::Ok && b.advance(20, &taken, &bad) == Status::Ok);
  CHECK(same_bits(a.state, b.state));
}

// The store grows the room it lacks: a rain of balls finds many more broadphase pairs
// than manifolds as it lands (a falling ball's box reaches ahead of it), and only the
// pairs' room grows for them; a world whose manifold room is too small grows that for
// the step that needs it. Either way the run is the same, bit for bit, as one that had
// the room from the start.
TEST(the_store_grows_the_room_a_step_lacks_and_steps_the_same) {
  auto build = [] {
    SceneBuilder s;
    s.ground(-6.0, 6.0);
    for (int i = 0; i < 400; ++i)  // rows of 20 from 1 m up, alternate rows shifted
      s.circle({-5.5 + 0.55 * (i % 20) + 0.25 * ((i / 20) % 2), 1.0 + 2.0 * (i / 20)}, 0.2, 1.0);
    return s;
  };
  SceneBuilder sa = build(), sb = build(), sc = build();
  World<2>& a = sa.finish();  // as made
  World<2>& b = sb.finish();  // room for everything from the start
  World<2>& c = sc.finish();  // room for 8 manifolds at first
  const std::int64_t room = a.contacts.capacity();
  CHECK(b.grow(16 * room));
  CHECK(c.contacts.grow(8));
  std::int64_t taken = 0, bad = -1;
  std::int64_t most_pairs = 0, most_manifolds = 0;
  for (int k = 0; k < 40; ++k) {
    CHECK(a.advance(5, &taken, &bad) == Status::Ok);
    most_pairs = std::max(most_pairs, a.contacts.count.pairs);
    most_manifolds = std::max(most_manifolds, a.contacts.count.manifolds);
  }
  CHECK(b.advance(200, &taken, &bad) == Status::Ok);
  CHECK(c.advance(200, &taken, &bad) == Status::Ok);
  // the pairs outgrew the room they had, the manifolds never did
  CHECK(most_pairs > room && most_manifolds < room);
  CHECK(a.contacts.pair_capacity() >= most_pairs && a.contacts.capacity() == room);
  // the manifolds outgrew 8 and got their room
  CHECK(c.contacts.capacity() >= most_manifolds && c.contacts.count.manifolds > 8);
  CHECK(same_bits(a.state, b.state));
  CHECK(same_bits(a.state, c.state));
}

// A bad state is found wherever it lies: each component of each body's position,
// velocity, spin and rotation in turn made NaN, infinite or (a position) past
// POSITION_LIMIT, in worlds of 1 to 9 bodies (the check runs over the arrays LANES
// doubles at a time, then the rest one by one: every place in both), is refused before
// a step and names that body.
TEST(a_bad_value_anywhere_in_the_state_names_its_body) {
  constexpr double NAN_ = std::numeric_limits<double>::quiet_NaN();
  constexpr double INF = std::numeric_limits<double>::infinity();
  for (int n = 1; n <= 9; ++n) {
    SceneBuilder s;
    for (int i = 0; i < n; ++i) s.circle({3.0 * i, 10.0}, 0.5, 1.0);
    World<2>& w = s.finish();
    State<2>& st = w.state;
    std::int64_t taken = 0, bad = -1;
    CHECK(w.advance(1, &taken, &bad) == Status::Ok);
    const State<2> good = st;
    for (int i = 0; i < n; ++i) {
      for (int k = 0; k < 7; ++k) {  // x.x, x.y, v.x, v.y, ω, q.c, q.s
        for (const double value : {NAN_, INF, -INF, 2.0 * POSITION_LIMIT}) {
          if (k >= 2 && std::isfinite(value)) continue;  // (only a position has a limit)
          double* at = k < 2   ? &st.body_x[i].x + k
                       : k < 4 ? &st.body_v[i].x + (k - 2)
                       : k == 4 ? &st.body_w[i]
                                : &st.body_q[i].c + (k - 5);
          *at = value;
          bad = -1;
          CHECK(w.advance(1, &taken, &bad) == Status::NonFinite);
          CHECK(taken == 0 && bad == i);
          st = good;
        }
      }
    }
    CHECK(w.advance(1, &taken, &bad) == Status::Ok && taken == 1);
  }
}

RBSIM_TEST_MAIN
