// collide/broadphase.cpp: the grid finds exactly the pairs a brute-force test over the fat
// boxes finds, sorted, on random layouts (dense cells and hashed cells, big shapes among
// small), keeps them while shapes move, and says when the store is too small.
#include <algorithm>
#include <array>
#include <random>
#include <vector>

#include <cstdio>
#include <ctime>

#include "check.hpp"
#include "scene_builder.hpp"
#include "scene_builder3d.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::SceneBuilder3;

namespace {

using Pair = std::array<std::int32_t, 2>;

// Every pair (a < b) of shapes whose fat boxes overlap (touching counts), on different
// bodies, one of them dynamic: what find_pairs must return (in the plane or in space).
template <int D>
std::vector<Pair> brute_force(const World<D>& w) {
  const auto& m = w.model;
  const auto& fat = w.grid.shape_fat;
  std::vector<Pair> out;
  for (int a = 0; a < m.shape_count(); ++a) {
    for (int b = a + 1; b < m.shape_count(); ++b) {
      const int ba = m.shape_body[a], bb = m.shape_body[b];
      if (ba == bb || !(m.is_dynamic(ba) || m.is_dynamic(bb))) continue;
      const double* lo_a = &fat[a].lo.x;
      const double* hi_a = &fat[a].hi.x;
      const double* lo_b = &fat[b].lo.x;
      const double* hi_b = &fat[b].hi.x;
      bool apart = false;
      for (int d = 0; d < D; ++d) apart = apart || lo_b[d] > hi_a[d] || lo_a[d] > hi_b[d];
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

// ---- 3D ------------------------------------------------------------------------------

namespace {

std::vector<Pair> find3(World<3>& w) {
  test::collide3(w);
  return {w.contacts.pairs.begin(), w.contacts.pairs.begin() + w.contacts.count.pairs};
}

Quat random_turn(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return normalize(Quat{g(rng), g(rng), g(rng), g(rng)});
}

// n boxes, balls and capsules in clusters of `per` around centres `spread` m apart (some
// static), on a ground plane y <= -1 and beside an oblique plane (both big shapes).
World<3>& random_layout3(SceneBuilder3& s, std::mt19937& rng, int n, int per, double spread) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  s.plane({0.0, 1.0, 0.0}, -1.0);
  s.plane({std::sqrt(0.5), 0.0, std::sqrt(0.5)}, -2.0);
  for (int i = 0; i < n; ++i) {
    const int cluster = i / per;
    const Vec3 centre{spread * (cluster % 5), spread * ((cluster / 5) % 5), spread * (cluster / 25)};
    const Vec3 x = centre + Vec3{3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng)};
    const double mass = u(rng) < 0.15 ? 0.0 : 1.0;
    const Vec3 v{2.0 * u(rng) - 1.0, 2.0 * u(rng) - 1.0, 2.0 * u(rng) - 1.0};
    const double kind = u(rng);
    if (kind < 0.4) {
      const Vec3 h{0.05 + 0.3 * u(rng), 0.05 + 0.3 * u(rng), 0.05 + 0.3 * u(rng)};
      s.box(x, h, mass, {}, random_turn(rng), v);
    } else if (kind < 0.8) {
      s.sphere(x, 0.05 + 0.3 * u(rng), mass, {}, v);
    } else {
      const double l = 0.3 * u(rng);
      s.capsule(x, {-l, 0, 0}, {l, 0, 0}, 0.05 + 0.2 * u(rng), mass, {}, random_turn(rng));
    }
  }
  return s.finish();
}

}  // namespace

// Clusters close together: the occupied block fits the table, each cell its own bucket;
// the planes are big and meet the shapes near them.
TEST(pairs_in_space_equal_brute_force_on_dense_grid) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 rng(seed);
    SceneBuilder3 s;
    World<3>& w = random_layout3(s, rng, 150, 75, 3.0);
    const auto pairs = find3(w);
    CHECK(w.grid.meta.direct_buckets == 1);
    CHECK(w.grid.meta.big_count >= 2);  // the planes
    CHECK(pairs == brute_force(w));
    CHECK(pairs.size() > 50);
    int with_plane = 0;
    for (const Pair& p : pairs) with_plane += p[0] < 2;
    CHECK(with_plane > 5);  // the planes found shapes near them
  }
}

// Clusters hundreds of metres apart: hashed cells.
TEST(pairs_in_space_equal_brute_force_on_hashed_grid) {
  for (unsigned seed = 11; seed <= 15; ++seed) {
    std::mt19937 rng(seed);
    SceneBuilder3 s;
    World<3>& w = random_layout3(s, rng, 200, 8, 300.0);
    const auto pairs = find3(w);
    CHECK(w.grid.meta.direct_buckets == 0);
    CHECK(pairs == brute_force(w));
    CHECK(pairs.size() > 20);
  }
}

// A ground plane's box is bounded above (its normal is an axis), so a ball far above it
// is no pair; an oblique plane's box is unbounded, so every shape is its candidate.
TEST(plane_box_is_bounded_along_an_axis_normal_only) {
  SceneBuilder3 s;
  s.plane({0.0, 1.0, 0.0}, 0.0);
  s.sphere({0.0, 5.0, 0.0}, 0.5, 1.0);
  s.sphere({3.0, 0.4, 0.0}, 0.5, 1.0);
  World<3>& w = s.finish();
  const auto pairs = find3(w);
  CHECK((pairs.size() == 1 && pairs[0] == Pair{0, 2}));
  const auto& ground = w.grid.shape_aabb[0];
  CHECK(ground.hi.y < 0.1 && std::isinf(ground.lo.y) && std::isinf(ground.hi.x));
}

// Shapes moving by their velocities, a few jumping far: kept and re-queried pairs stay
// exact, and the list is sorted (a < b, keys ascending) every step.
TEST(kept_pairs_in_space_after_motion_equal_brute_force_sorted) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  SceneBuilder3 s;
  World<3>& w = random_layout3(s, rng, 120, 60, 3.0);
  find3(w);
  bool exact = true, sorted = true;
  int some_kept = 0;
  for (int k = 0; k < 40; ++k) {
    for (int i = 0; i < w.model.body_count(); ++i) {
      if (!w.model.is_dynamic(i)) continue;
      w.state.body_x[i] += 0.01 * w.state.body_v[i];
      if (u(rng) < 0.02) w.state.body_x[i] += Vec3{4.0 * u(rng) - 2.0, 4.0 * u(rng) - 2.0, 4.0 * u(rng) - 2.0};
    }
    const auto pairs = find3(w);
    int unmoved = 0;
    for (auto moved : w.grid.shape_moved) unmoved += !moved;
    some_kept += unmoved > 0;
    exact = exact && pairs == brute_force(w);
    for (std::size_t p = 0; p < pairs.size(); ++p) {
      sorted = sorted && pairs[p][0] < pairs[p][1];
      if (p > 0) sorted = sorted && (pairs[p - 1][0] < pairs[p][0] ||
                                     (pairs[p - 1][0] == pairs[p][0] && pairs[p - 1][1] < pairs[p][1]));
    }
  }
  CHECK(exact);
  CHECK(sorted);
  CHECK(some_kept > 30);
}

// The same layout built twice gives the same pairs in the same order (no dependence on
// addresses or timing).
TEST(pairs_in_space_are_deterministic) {
  std::vector<Pair> first;
  for (int run = 0; run < 2; ++run) {
    std::mt19937 rng(3);
    SceneBuilder3 s;
    World<3>& w = random_layout3(s, rng, 150, 75, 3.0);
    const auto pairs = find3(w);
    if (run == 0) first = pairs;
    else CHECK(pairs == first);
  }
}

// Not a test of speed (none is asserted): the time per step of find_pairs for 1000
// spheres in a box (10 x 10 x 10, 1.02 m apart, r 0.5) at rest, and with every sphere
// moved past its fat box each step (the worst case of a poured pile).
TEST(measure_pairs_of_1000_spheres_in_a_box) {
  SceneBuilder3 s;
  s.plane({0.0, 1.0, 0.0}, 0.0);
  for (double n : {-1.0, 1.0}) {
    s.plane({n, 0.0, 0.0}, -5.6);  // the walls x <= -5.6, x >= 5.6
    s.plane({0.0, 0.0, n}, -5.6);
  }
  for (int i = 0; i < 1000; ++i)
    s.sphere({1.02 * (i % 10) - 4.6, 0.5 + 1.02 * ((i / 10) % 10), 1.02 * (i / 100) - 4.6}, 0.5, 1.0);
  World<3>& w = s.finish();
  find3(w);
  // µs of this thread's CPU time (the machine may be shared: wall time would count others)
  auto now = [] {
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return 1e6 * static_cast<double>(t.tv_sec) + 1e-3 * static_cast<double>(t.tv_nsec);
  };
  const int reps = 200;
  double transform = 0.0, still = 0.0, moving = 0.0;
  for (int r = 0; r < reps; ++r) {
    double t0 = now();
    transform_shapes(w.model, w.state, w.contacts, w.config.dt);
    const double t1 = now();
    w.contacts.count.pairs = find_pairs(w.model, w.grid, w.contacts);
    transform += t1 - t0;
    still += now() - t1;
  }
  const std::int64_t n_still = w.contacts.count.pairs;
  for (int r = 0; r < reps; ++r) {
    const double dx = (r % 2 ? 1.0 : -1.0) * 0.03;  // beyond the 2 cm fat margin
    for (int i = 0; i < w.model.body_count(); ++i)
      if (w.model.is_dynamic(i)) w.state.body_x[i].x += dx;
    transform_shapes(w.model, w.state, w.contacts, w.config.dt);
    const double t0 = now();
    w.contacts.count.pairs = find_pairs(w.model, w.grid, w.contacts);
    moving += now() - t0;
  }
  std::printf("1000 spheres in a box (CPU time per step): transform %.1f us; find_pairs %.1f us "
              "at rest, %.1f us with every sphere moved (%lld pairs)\n",
              transform / reps, still / reps, moving / reps,
              static_cast<long long>(w.contacts.count.pairs));
  CHECK(n_still == w.contacts.count.pairs);
  CHECK(find3(w) == brute_force(w));
}

RBSIM_TEST_MAIN
