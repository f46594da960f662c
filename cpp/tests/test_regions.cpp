// solver/regions.cpp: the regions of the threaded solver passes.
#include "check.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

namespace {

// A row of n unit boxes side by side on the ground, touching, centred on x = 0.
World<2>& row_of_boxes(SceneBuilder& s, int n) {
  s.ground(-2.0 * n, 2.0 * n);
  for (int i = 0; i < n; ++i) s.box({i - 0.5 * (n - 1), 0.5}, 0.5, 0.5, 1.0);
  return s.finish();
}

}  // namespace

// Below SOLVER_REGIONS * REGION_MIN_BODIES dynamic bodies: one region, the solve order
// as support_order left it, all in segment 0.
TEST(a_small_scene_is_one_region) {
  SceneBuilder s;
  World<2>& w = row_of_boxes(s, 10);
  rbsim::test::collide(w);
  auto& c = w.contacts;
  partition_regions(w.model, w.state, c);
  const std::int64_t n = c.count.manifolds;
  CHECK(n > 0);
  CHECK(c.region_count == 1);
  CHECK(c.segment_order[0] == 0 && c.segment_order[1] == n && c.segment_order[2] == n);
  for (int i = 1; i < w.model.body_count(); ++i) CHECK(c.body_region[i] == 0);
  CHECK(c.body_region[0] == -1);  // the static ground
}

// A row long enough to split: two strips of equal count, left and right; each region's
// manifolds first (those with the ground or within the strip), then the one contact
// between the two boxes at the cut; every segment in solve order (ground first).
TEST(a_large_scene_is_cut_across_gravity) {
  const int n = 2 * constants::REGION_MIN_BODIES;
  SceneBuilder s;
  World<2>& w = row_of_boxes(s, n);
  rbsim::test::collide(w);
  auto& c = w.contacts;
  partition_regions(w.model, w.state, c);
  CHECK(c.region_count == constants::SOLVER_REGIONS);
  int left = 0, right = 0;
  for (int i = 1; i <= n; ++i) {
    const int r = c.body_region[i];
    CHECK(r == (w.state.body_x[i].x < 0.0 ? 0 : 1));
    left += r == 0;
    right += r == 1;
  }
  CHECK(left == right);
  const std::int64_t m = c.count.manifolds;
  const auto& seg = c.segment_order;
  CHECK(seg[0] == 0 && seg[segment_count(2)] == m);
  CHECK(seg[3] - seg[2] == 1);  // the cut between regions 0 and 1: one box-box contact
  for (int g = 0; g < 2; ++g) {
    for (std::int64_t o = seg[g]; o < seg[g + 1]; ++o) {
      const std::int32_t k = c.solve_order[o];
      for (const int b : {c.body_a[k], c.body_b[k]})
        CHECK(c.body_region[b] == g || c.body_region[b] == -1);
    }
  }
  // ground contacts (level 0 supporter) before the box-box ones within a region
  bool seen_box_box = false, ordered = true;
  for (std::int64_t o = seg[0]; o < seg[1]; ++o) {
    const std::int32_t k = c.solve_order[o];
    const bool ground = c.body_a[k] == 0 || c.body_b[k] == 0;
    if (!ground) seen_box_box = true;
    if (ground && seen_box_box) ordered = false;
  }
  CHECK(ordered);
}

RBSIM_TEST_MAIN
