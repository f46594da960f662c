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

// A heap of 30 boxes and balls dropped on the ground lands and settles. While most of its
// pairs move the step's store leaves the manifolds in the current arrays, and the next
// step swaps them into prev_* (take_prev) instead; in the settled heap it copies them.
// Two worlds stepped alike, one with the hand-over made a copy after every step
// (settle_prev, as store_impulses would), stay the same to the bit, and the swap leaves in
// prev_* what the copy does.
TEST(a_store_swapped_at_the_next_step_gives_what_a_copy_gives) {
  auto heap = [](SceneBuilder& s) {
    s.ground(-4.0, 4.0);
    for (int i = 0; i < 15; ++i) {
      s.box({-2.0 + 0.6 * (i % 5), 0.4 + 0.7 * (i / 5)}, 0.25, 0.2, 1.0, {0.5, 0.0}, 0.2 * i);
      s.circle({-1.7 + 0.6 * (i % 5), 2.6 + 0.6 * (i / 5)}, 0.2, 0.8, {0.5, 0.0}, {0.2, -1.0});
    }
  };
  SceneBuilder s1, s2;
  heap(s1);
  heap(s2);
  World<2>& w1 = s1.finish();
  World<2>& w2 = s2.finish();
  auto& c1 = w1.contacts;
  auto& c2 = w2.contacts;
  int swapped = 0, copied = 0;  // steps
  bool same = true, same_prev = true, compared = false;
  for (int k = 0; k < 300; ++k) {
    CHECK(w1.step());
    CHECK(w2.step());
    (c1.prev_pending ? swapped : copied) += c1.count.manifolds > 0;
    settle_prev(c2);
    same = same && rbsim::test::same_bits(w1.state, w2.state);
    if (k < 20 || !c1.prev_pending || compared) continue;
    // once, in the landing: the swap made now (as the next step's start would) leaves in
    // prev_* what the copy left
    take_prev(c1);
    compared = true;
    CHECK(c1.prev_swapped && !c1.prev_pending);
    CHECK(c1.count.manifolds_prev == c2.count.manifolds_prev);
    for (std::int64_t m = 0; m < c1.count.manifolds_prev; ++m) {
      same_prev = same_prev && c1.prev_key[m] == c2.prev_key[m] && c1.key[m] == c2.key[m] &&
                  c1.prev_points[m] == c2.prev_points[m] &&
                  c1.prev_normal[m].x == c2.prev_normal[m].x &&
                  c1.prev_normal[m].y == c2.prev_normal[m].y;
      for (int j = 0; j < c1.prev_points[m]; ++j)
        same_prev = same_prev && c1.prev_feature[m][j] == c2.prev_feature[m][j] &&
                    c1.prev_anchor_a[m][j].x == c2.prev_anchor_a[m][j].x &&
                    c1.prev_sep_anchor_b[m][j].y == c2.prev_sep_anchor_b[m][j].y &&
                    c1.prev_ref_separation[m][j] == c2.prev_ref_separation[m][j] &&
                    c1.prev_normal_impulse[m][j] == c2.prev_normal_impulse[m][j] &&
                    c1.prev_tangent_impulse[m][j] == c2.prev_tangent_impulse[m][j];
    }
  }
  CHECK(same);
  CHECK(compared && same_prev);
  CHECK(swapped > 10);  // the landing
  CHECK(copied > 10);   // the settled heap
}

RBSIM_TEST_MAIN
