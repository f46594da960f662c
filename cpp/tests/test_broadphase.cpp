// collide/broadphase.cpp: the grid finds exactly the pairs a brute-force test over the fat
// boxes finds, sorted, on random layouts (dense cells and hashed cells, big shapes among
// small), keeps them while shapes move, and says when the store is too small.
#include <algorithm>
#include <array>
#include <random>
#include <vector>

#include "check.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

namespace {

using Pair = std::array<std::int32_t, 2>;

// Every pair (a < b) of shapes whose fat boxes overlap (touching counts), on different
// bodies, one of them dynamic: what find_pairs must return.
std::vector<Pair> brute_force(const World<2>& w) {
  const auto& m = w.model;
  const auto& fat = w.grid.shape_fat;
  std::vector<Pair> out;
  for (int a = 0; a < m.shape_count(); ++a) {
    for (int b = a + 1; b < m.shape_count(); ++b) {
      const int ba = m.shape_body[a], bb = m.shape_body[b];
      if (ba == bb || !(m.is_dynamic(ba) || m.is_dynamic(bb))) continue;
      const bool apart = fat[b].lo.x > fat[a].hi.x || fat[a].lo.x > fat[b].hi.x ||
                         fat[b].lo.y > fat[a].hi.y || fat[a].lo.y > fat[b].hi.y;
      if (!apart) out.push_back({a, b});
    }
  }
  return out;
}

// Transform and find pairs (growing the store as the step does); the pairs found.
std::vector<Pair> find(World<2>& w) {
  transform_shapes(w.model, w.state, w.contacts, w.config.dt);
  std::int64_t n = find_pairs(w.model, w.grid, w.contacts);
  while (n > w.contacts.capacity()) {
    w.grow(2 * n);
    n = find_pairs(w.model, w.grid, w.contacts);
  }
  w.contacts.count.pairs = n;
  return {w.contacts.pairs.begin(), w.contacts.pairs.begin() + n};
}

// n boxes and balls in clusters of `per` around centres `spread` m apart (some static),
// with a long static ground under the first cluster (a big shape).
World<2>& random_layout(SceneBuilder& s, std::mt19937& rng, int n, int per, double spread) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  s.segment({-3.0, -1.0}, {3.0 + spread, -1.0});
  for (int i = 0; i < n; ++i) {
    const int cluster = i / per;
    const Vec2 centre{spread * (cluster % 7), spread * (cluster / 7)};
    const Vec2 x = centre + Vec2{3.0 * u(rng), 3.0 * u(rng)};
    const double mass = u(rng) < 0.15 ? 0.0 : 1.0;  // some static bodies
    const Vec2 v{2.0 * u(rng) - 1.0, 2.0 * u(rng) - 1.0};
    if (u(rng) < 0.5)
      s.box(x, 0.05 + 0.3 * u(rng), 0.05 + 0.3 * u(rng), mass, {}, 3.0 * u(rng), v);
    else
      s.circle(x, 0.05 + 0.3 * u(rng), mass, {}, v);
  }
  return s.finish();
}

}  // namespace

// Clusters close together: the occupied cells fit the table, each cell its own bucket.
TEST(pairs_equal_brute_force_on_dense_grid) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 rng(seed);
    SceneBuilder s;
    World<2>& w = random_layout(s, rng, 120, 40, 4.0);
    const auto pairs = find(w);
    CHECK(w.grid.meta.direct_buckets == 1);
    CHECK(w.grid.meta.big_count >= 1);  // the ground
    CHECK(pairs == brute_force(w));
    CHECK(pairs.size() > 50);  // the layouts are crowded enough to test something
  }
}

// Clusters hundreds of metres apart: the occupied rectangle has more cells than the table
// has buckets, so the cells are hashed (and buckets hold other cells' entries).
TEST(pairs_equal_brute_force_on_hashed_grid) {
  for (unsigned seed = 11; seed <= 15; ++seed) {
    std::mt19937 rng(seed);
    SceneBuilder s;
    World<2>& w = random_layout(s, rng, 150, 10, 300.0);
    const auto pairs = find(w);
    CHECK(w.grid.meta.direct_buckets == 0);
    CHECK(pairs == brute_force(w));
    CHECK(pairs.size() > 20);
  }
}

// Shapes moving by their velocities, a few jumping far: the pairs of shapes that stayed
// in their fat boxes are kept, the moved ones queried again; the list stays exact.
TEST(kept_pairs_after_motion_equal_brute_force) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  SceneBuilder s;
  World<2>& w = random_layout(s, rng, 100, 50, 3.0);
  find(w);
  bool exact = true;
  int some_kept = 0;
  for (int k = 0; k < 40; ++k) {
    for (int i = 0; i < w.model.body_count(); ++i) {
      if (!w.model.is_dynamic(i)) continue;
      w.state.body_x[i] += 0.01 * w.state.body_v[i];
      if (u(rng) < 0.02) w.state.body_x[i] += Vec2{4.0 * u(rng) - 2.0, 4.0 * u(rng) - 2.0};
    }
    const auto pairs = find(w);
    int unmoved = 0;
    for (auto moved : w.grid.shape_moved) unmoved += !moved;
    some_kept += unmoved > 0;
    exact = exact && pairs == brute_force(w);
  }
  CHECK(exact);
  CHECK(some_kept > 30);  // most updates kept some shapes' pairs
}

// More overlapping pairs than the store holds: find_pairs returns how many it needs;
// after the store grows to that, the list is found complete.
TEST(store_too_small_returns_the_pair_count_needed) {
  SceneBuilder s;
  for (int i = 0; i < 30; ++i) s.box({0.01 * i, 0.02 * i}, 0.5, 0.5, 1.0);  // all overlap
  World<2>& w = s.finish();
  const std::int64_t need = 30 * 29 / 2;
  CHECK(w.contacts.capacity() < need);
  transform_shapes(w.model, w.state, w.contacts, w.config.dt);
  const std::int64_t n = find_pairs(w.model, w.grid, w.contacts);
  CHECK(n == need);
  w.grow(n);
  CHECK(w.contacts.capacity() >= need);
  const std::int64_t again = find_pairs(w.model, w.grid, w.contacts);
  CHECK(again == need);
  std::vector<Pair> pairs(w.contacts.pairs.begin(), w.contacts.pairs.begin() + again);
  CHECK(pairs == brute_force(w));
}

RBSIM_TEST_MAIN
