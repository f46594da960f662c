// collide/transform.cpp: world geometry of every shape and its speculative reach.
#include <bit>
#include <cmath>
#include <cstdint>

#include "check.hpp"
#include "rbsim/constants.hpp"
#include "scene_builder.hpp"
#include "scene_builder3d.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::SceneBuilder3;

namespace {
constexpr double EPS = 1e-14;  // m: round-off of O(1) coordinates
rbsim::Vec3 normalize_axis(rbsim::Vec3 a) { return (1.0 / length(a)) * a; }
}

// A turned, moved box: each world vertex is x + R(θ) l, each world normal R(θ) n.
TEST(world_vertices_are_body_vertices_turned_and_moved) {
  SceneBuilder s;
  s.ground();
  const double angle = 0.3;
  const int b = s.box({1.5, 2.0}, 0.5, 0.25, 1.0, {}, angle);
  World<2>& w = s.finish();
  transform_shapes(w.model, w.state, w.contacts, w.config.dt);
  const Rot2 q{std::cos(angle), std::sin(angle)};
  const int k0 = w.model.shape_vstart[b];
  for (int k = k0; k < k0 + 4; ++k) {
    const Vec2 want = Vec2{1.5, 2.0} + rotate(q, w.model.vertex_local[k]);
    CHECK_NEAR(w.contacts.vert_world[k].x, want.x, EPS);
    CHECK_NEAR(w.contacts.vert_world[k].y, want.y, EPS);
    const Vec2 n = rotate(q, w.model.normal_local[k]);
    CHECK_NEAR(w.contacts.norm_world[k].x, n.x, EPS);
    CHECK_NEAR(w.contacts.norm_world[k].y, n.y, EPS);
  }
  // the first edge's normal is the bottom face's, -y turned by θ
  CHECK_NEAR(w.contacts.norm_world[k0].x, std::sin(angle), EPS);
  CHECK_NEAR(w.contacts.norm_world[k0].y, -std::cos(angle), EPS);
}

// How far the surface can move in a step: dt |ω| r_max by turning (r_max the farthest
// core vertex: a circle turning about its centre moves no surface); the box reaches
// |dt v - frame| + dt² |g| + the turn about the frame's move
// (the median of the dynamic bodies' moves in the last step along each axis, the lower
// middle one of two), a static shape's |frame|.
TEST(speculative_reach_is_dt_times_surface_speed) {
  SceneBuilder s;
  const int g = s.ground();
  const int ball = s.circle({0, 3}, 0.25, 1.0, {}, {3.0, -4.0}, 2.0);
  const int box = s.box({2, 3}, 0.3, 0.4, 1.0, {}, 0.0, {0.0, 1.0}, -10.0);
  World<2>& w = s.finish(0.01);
  auto& c = w.contacts;
  const int bb = w.model.shape_body[ball], bx = w.model.shape_body[box];
  c.body_delta[bb].dx = {0.02, -0.04};  // last step's moves
  c.body_delta[bx].dx = {0.0, 0.01};
  const Vec2 frame = frame_move(w.model, c);
  CHECK(frame.x == 0.0 && frame.y == -0.04);
  transform_shapes(w.model, w.state, c, w.config.dt);
  CHECK(c.shape_turn[g] == 0.0);
  CHECK(c.shape_turn[ball] == 0.0);  // its spin moves no surface
  CHECK_NEAR(c.shape_turn[box], 0.01 * 10.0 * 0.5, EPS);  // corner at 0.5 m
  const Vec2 step{0.03, -0.04};  // the ball's, m
  const double fall = 0.01 * 0.01 * 9.81;  // m
  CHECK_NEAR(c.shape_margin[g], 0.04, EPS);
  CHECK_NEAR(c.shape_margin[ball], length(step - frame) + fall, EPS);
  const Vec2 step_box{0.0, 0.01};
  CHECK_NEAR(c.shape_margin[box], length(step_box - frame) + fall + 0.05, EPS);
}

// ---- 3D ------------------------------------------------------------------------------

namespace {
// A unit quaternion for a turn of `angle` (rad) about the unit axis a.
Quat turn(Vec3 a, double angle) {
  const double s = std::sin(0.5 * angle);
  return {std::cos(0.5 * angle), s * a.x, s * a.y, s * a.z};
}
}  // namespace

// A turned, moved box, capsule and tetrahedron in space: each world vertex is x + R(q) l;
// a plane's world normal and point are its body's; a hull's face normals are R(q) n_f.
TEST(world_geometry_in_space_is_body_geometry_turned_and_moved) {
  SceneBuilder3 s;
  const int g = s.plane({0.0, 1.0, 0.0}, -0.5);
  const Quat q = turn(normalize_axis({1.0, 2.0, 0.5}), 0.7);
  const Vec3 x{1.5, 2.0, -0.5};
  const int b = s.box(x, {0.5, 0.25, 0.1}, 1.0, {}, q);
  const int cap = s.capsule({0, 4, 0}, {-0.3, 0, 0}, {0.3, 0, 0}, 0.1, 1.0, {}, q);
  const std::vector<Vec3> tet{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const int t = s.convex({3, 3, 3}, tet, {{{0, 2, 1}}, {{0, 1, 3}}, {{0, 3, 2}}, {{1, 2, 3}}}, 1.0, {}, q);
  World<3>& w = s.finish();
  transform_shapes(w.model, w.state, w.contacts, w.config.dt);
  const auto& m = w.model;
  for (int shape : {b, cap, t}) {
    const int i = m.shape_body[shape];
    for (int k = m.shape_vstart[shape]; k < m.shape_vstart[shape] + m.shape_vcount[shape]; ++k) {
      const Vec3 want = w.state.body_x[i] + rotate(q, m.vertex_local[k]);
      CHECK(length(w.contacts.vert_world[k] - want) < EPS);
    }
  }
  const int k = m.shape_vstart[g];
  CHECK(w.contacts.norm_world[k].y == 1.0 && w.contacts.vert_world[k].y == -0.5);
  const Hull3& hull = m.shape_hull[t];
  CHECK(hull.face_count() == 4 && m.hull_face_count == 4);
  for (int f = 0; f < 4; ++f) {
    const Vec3 want = rotate(q, hull.face_normal[f]);
    CHECK(length(w.contacts.face_world[m.shape_hface[t] + f] - want) < EPS);
  }
  // the slanted face's world normal is (1, 1, 1)/√3 turned
  const Vec3 slanted = rotate(q, (1.0 / std::sqrt(3.0)) * Vec3{1, 1, 1});
  bool found = false;
  for (int f = 0; f < 4; ++f)
    found = found || length(w.contacts.face_world[m.shape_hface[t] + f] - slanted) < EPS;
  CHECK(found);
}

// The reach in space: |ω| the vector's length; the frame's move the lower middle one of
// the two dynamic bodies' along each axis.
TEST(speculative_reach_in_space_is_dt_times_surface_speed) {
  SceneBuilder3 s;
  const int g = s.plane({0.0, 1.0, 0.0}, 0.0);
  const int ball = s.sphere({0, 3, 0}, 0.25, 1.0, {}, {3.0, -4.0, 0.0});
  const int box = s.box({2, 3, 0}, {0.3, 0.4, 0.0}, 1.0, {}, {}, {0.0, 1.0, 0.0}, {6.0, 0.0, 8.0});
  World<3>& w = s.finish(0.01);
  auto& c = w.contacts;
  const int bb = w.model.shape_body[ball], bx = w.model.shape_body[box];
  c.body_delta[bb].dx = {0.02, -0.04, 0.01};
  c.body_delta[bx].dx = {0.0, 0.01, 0.03};
  const Vec3 frame = frame_move(w.model, c);
  CHECK(frame.x == 0.0 && frame.y == -0.04 && frame.z == 0.01);
  transform_shapes(w.model, w.state, c, w.config.dt);
  CHECK(c.shape_turn[g] == 0.0 && c.shape_turn[ball] == 0.0);
  CHECK_NEAR(c.shape_turn[box], 0.01 * 10.0 * 0.5, EPS);  // corner at 0.5 m
  const Vec3 step{0.03, -0.04, 0.0};  // the ball's, m
  const double fall = 0.01 * 0.01 * 9.81;  // m
  CHECK_NEAR(c.shape_margin[g], length(frame), EPS);
  CHECK_NEAR(c.shape_margin[ball], length(step - frame) + fall, EPS);
  const Vec3 step_box{0.0, 0.01, 0.0};
  CHECK_NEAR(c.shape_margin[box], length(step_box - frame) + fall + 0.05, EPS);
}

RBSIM_TEST_MAIN

// Static segments laid end to end know the segment that continues each end (its far
// end, world frame); an end where three meet (a fork) and a free end know none.
TEST(segments_laid_end_to_end_know_their_neighbours) {
  SceneBuilder s;
  s.segment({0.0, 0.0}, {1.0, 0.0});   // shape 0
  s.segment({1.0, 0.0}, {2.0, 0.0});   // shape 1: continues 0
  s.segment({2.0, 0.0}, {3.0, 1.0});   // shape 2: a fork at (2, 0) with 1 and 3
  s.segment({2.0, 0.0}, {3.0, -1.0});  // shape 3
  s.box({0.5, 1.0}, 0.2, 0.2, 1.0);    // something that moves
  World<2>& w = s.finish();
  const auto& g = w.model.segment_ghost;
  CHECK(g.size() == 5);
  auto none = [](Vec2 p) { return std::isnan(p.x) && std::isnan(p.y); };
  CHECK(none(g[0][0]));
  CHECK_NEAR(g[0][1].x, 2.0, EPS);  // 0's end (1, 0) goes on to 1's far end
  CHECK_NEAR(g[0][1].y, 0.0, EPS);
  CHECK_NEAR(g[1][0].x, 0.0, EPS);
  CHECK_NEAR(g[1][0].y, 0.0, EPS);
  CHECK(none(g[1][1]) && none(g[2][0]) && none(g[3][0]));  // the fork
  CHECK(none(g[2][1]) && none(g[3][1]) && none(g[4][0]) && none(g[4][1]));
}

// A face of a static box that lies flush against another static shape's face, which
// covers all of it, is covered (find_covered_faces: 2D edge k from corner k to k + 1,
// corners counter-clockwise from (-w, -h)); a face a taller neighbour or a gap leaves
// partly open is not, and a dynamic body's faces never are.
TEST(flush_faces_of_static_boxes_side_by_side_are_covered) {
  SceneBuilder s;
  s.box({0.25, -0.1}, 0.25, 0.1, 0.0);           // 0: a tile, its top at y = 0
  s.box({0.75, -0.1}, 0.25, 0.1, 0.0);           // 1: the next, flush against 0
  s.box({1.25, -0.05}, 0.25, 0.15, 0.0);         // 2: taller (to y = 0.1), flush against 1
  s.box({1.75 + 1e-3, -0.05}, 0.25, 0.15, 0.0);  // 3: 1 mm from 2
  s.box({0.5, 1.0}, 0.2, 0.2, 1.0);              // 4: dynamic
  World<2>& w = s.finish();
  const auto& covered = w.model.shape_covered;
  CHECK(covered.size() == 5);
  CHECK(covered[0] == 1u << 1);                // its right side
  CHECK(covered[1] == ((1u << 1) | (1u << 3)));  // both sides (the right one by 2's taller one)
  CHECK(covered[2] == 0u);  // its left side is open above tile 1, its right one by the gap
  CHECK(covered[3] == 0u);
  CHECK(covered[4] == 0u);
  // tile 2's left side is covered near its lower corner (its loop's second: the side runs
  // from corner 3, top left, to corner 0), and every corner of a wholly covered face
  const auto& corner = w.model.corner_covered;
  const auto& rows = w.model.corner_start;
  CHECK(rows.size() == 6 && rows[1] == 4 && rows[2] == 8 && rows[3] == 12 && rows[5] == 12);
  CHECK(corner[rows[2] + 3] == 2u && corner[rows[2] + 1] == 0u);
  CHECK(corner[rows[0] + 1] == 3u && corner[rows[1] + 3] == 3u && corner[rows[0] + 3] == 0u);
  // and who lies against them: 0's right side tile 1, 1's sides tiles 0 and 2, 2's tile 1
  const auto& start = w.model.cover_start;
  const auto& by = w.model.cover;
  CHECK(start.size() == 6 && start[0] == 0 && start[1] == 1 && start[2] == 3 && start[3] == 4 &&
        start[5] == 4);
  CHECK(by[0].shape == 1 && by[0].faces == 1u << 1);
  CHECK(by[1].shape == 0 && by[1].faces == 1u << 3);
  CHECK(by[2].shape == 2 && by[2].faces == 1u << 1);
  CHECK(by[3].shape == 1 && by[3].faces == 1u << 3);
}

// In 3D a face may be covered by several (bricks laid in bond: the upper brick's bottom
// rests on two); a box's faces go -x, +x, -y, +y, -z, +z (box_hull()'s order).
TEST(a_brick_face_resting_on_two_bricks_is_covered) {
  SceneBuilder3 s;
  s.box({0.5, 0.25, 0.1}, {0.5, 0.25, 0.1}, 0.0);   // 0: [0, 1] x [0, 0.5]
  s.box({1.5, 0.25, 0.1}, {0.5, 0.25, 0.1}, 0.0);   // 1: [1, 2], flush against 0
  s.box({1.0, 0.75, 0.1}, {0.5, 0.25, 0.1}, 0.0);   // 2: on both, [0.5, 1.5] x [0.5, 1]
  s.box({3.0, 0.25, 0.1}, {0.5, 0.25, 0.1}, 0.0);   // 3: 0.5 m from 1
  s.box({5.0, 0.25, 0.1}, {0.5, 0.25, 0.1}, 1.0);   // 4: dynamic
  World<3>& w = s.finish();
  const auto& covered = w.model.shape_covered;
  CHECK(covered.size() == 5);
  CHECK(covered[0] == 1u << 1);  // +x; its top is half open
  CHECK(covered[1] == 1u << 0);  // -x
  CHECK(covered[2] == 1u << 2);  // -y: on the two below
  CHECK(covered[3] == 0u);
  CHECK(covered[4] == 0u);
  // who lies against them: 0's +x brick 1 and its top (half covered) brick 2; 1's -x
  // brick 0 and its top brick 2; 2's bottom bricks 0 and 1
  const auto& start = w.model.cover_start;
  const auto& by = w.model.cover;
  CHECK(start.size() == 6 && start[1] == 2 && start[2] == 4 && start[3] == 6 && start[5] == 6);
  CHECK(by[0].shape == 1 && by[0].faces == 1u << 1 && by[1].shape == 2 && by[1].faces == 1u << 3);
  CHECK(by[2].shape == 0 && by[2].faces == 1u << 0 && by[3].shape == 2 && by[3].faces == 1u << 3);
  CHECK(by[4].shape == 0 && by[5].shape == 1 && by[4].faces == 1u << 2 && by[5].faces == 1u << 2);
  // brick 0's top is covered near the two corners over x = 1, not the two over x = 0
  const auto& corner = w.model.corner_covered;
  const std::uint64_t top = corner[w.model.corner_start[0] + 3];
  CHECK(std::popcount(top) == 2);
}

// A ground plane covers the faces lying in it, turned down into it: a wall standing on
// the plane has its bottom face covered, with the plane as its neighbour; a box lifted
// 1 cm off the plane, and a dynamic one standing on it, have none.
TEST(a_face_standing_on_a_ground_plane_is_covered) {
  SceneBuilder3 s;
  s.plane({0, 1, 0}, 0.0);                         // 0
  s.box({-2.1, 2.0, 0.0}, {0.1, 2.0, 3.0}, 0.0);   // 1: a wall on the plane
  s.box({2.0, 0.26, 0.0}, {0.25, 0.25, 0.25}, 0.0);  // 2: 1 cm above it
  s.box({4.0, 0.25, 0.0}, {0.25, 0.25, 0.25}, 1.0);  // 3: dynamic, on it
  World<3>& w = s.finish();
  const auto& covered = w.model.shape_covered;
  CHECK(covered.size() == 4);
  CHECK(covered[1] == 1u << 2);  // -y
  CHECK(covered[2] == 0u);
  CHECK(covered[3] == 0u);
  const auto& start = w.model.cover_start;
  CHECK(start[1] == 0 && start[2] == 1 && start[4] == 1);
  CHECK(w.model.cover[0].shape == 0 && w.model.cover[0].faces == 1u << 2);
}

// Flush to FLUSH_DISTANCE, round-off aside: a wall placed to three decimals (centre
// 2.601, height 5.201) stands 0.5 mm over the floor's top in decimals, a few 1e-16 m more
// in binary, and is on it; 0.6 mm over it, it is not.
TEST(a_wall_placed_to_three_decimals_stands_flush_on_the_floor) {
  for (const double centre : {2.601, 2.6011}) {
    SceneBuilder s;
    s.box({0.0, -0.5}, 3.7, 0.5, 0.0);        // 0: the floor, top at y = 0
    s.box({3.2, centre}, 0.5, 5.201 / 2, 0.0);  // 1: a wall, its foot at centre - 2.6005
    s.box({0.0, 1.0}, 0.1, 0.1, 1.0);         // 2: dynamic
    World<2>& w = s.finish();
    const bool flush = centre == 2.601;
    CHECK(!w.model.shape_covered.empty() || !flush);
    if (!w.model.shape_covered.empty()) CHECK((w.model.shape_covered[1] == 1u << 0) == flush);
  }
}
