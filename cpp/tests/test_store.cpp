// contact/store.cpp: this step's manifolds become last step's.
#include "check.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

// Two boxes stacked on the ground: every manifold's key, points, normal, anchors, ids and
// impulses are copied to prev_*, and the points that pushed are counted.
TEST(store_copies_manifolds_and_counts_points_that_pushed) {
  SceneBuilder s;
  s.ground();
  s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
  s.box({0.0, 1.5}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  auto& c = w.contacts;
  rbsim::test::collide(w);
  CHECK(c.count.manifolds == 2);
  for (int m = 0; m < 2; ++m) {
    c.normal_impulse[m] = {1.0 + m, 0.5};
    c.tangent_impulse[m] = {0.1, -0.1 * m};
    c.max_normal_impulse[m] = {m == 0 ? 1.0 : 0.0, 0.5};  // 3 of 4 points pushed
  }
  store_impulses(c);
  CHECK(c.count.manifolds_prev == 2);
  CHECK(c.count.points_touching == 3);
  for (int m = 0; m < 2; ++m) {
    CHECK(c.prev_key[m] == c.key[m]);
    CHECK(c.prev_points[m] == c.points[m]);
    CHECK(c.prev_normal[m].y == c.normal[m].y);
    for (int k = 0; k < 2; ++k) {
      CHECK(c.prev_feature[m][k] == c.feature[m][k]);
      CHECK(c.prev_anchor_a[m][k].x == c.anchor_a[m][k].x);
      CHECK(c.prev_ref_separation[m][k] == c.ref_separation[m][k]);
      CHECK(c.prev_normal_impulse[m][k] == c.normal_impulse[m][k]);
      CHECK(c.prev_tangent_impulse[m][k] == c.tangent_impulse[m][k]);
    }
  }
}

// A carried manifold's slot already holds its geometry: only the impulses are copied.
TEST(store_of_carried_slot_copies_only_impulses) {
  SceneBuilder s;
  s.ground();
  s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  auto& c = w.contacts;
  rbsim::test::collide(w);
  store_impulses(c);
  c.carried[0] = 1;
  c.normal[0] = {1.0, 0.0};  // would be copied were the slot not carried
  c.normal_impulse[0] = {0.7, 0.8};
  store_impulses(c);
  CHECK(c.prev_normal[0].x == 0.0);
  CHECK(c.prev_normal_impulse[0][0] == 0.7 && c.prev_normal_impulse[0][1] == 0.8);
}

RBSIM_TEST_MAIN
