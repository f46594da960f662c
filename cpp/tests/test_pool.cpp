// tools/pool.cpp: the worker pool runs every task once, on any number of threads, and
// returns only when all are done.
#include <atomic>
#include <vector>

#include "check.hpp"
#include "rbsim/pool.hpp"

using namespace rbsim;

// Each task writes its own slot: every slot written exactly once, on 1, 2 and 3 threads,
// over many calls in a row (a worker that wakes late for a call takes no task of the next).
TEST(every_task_runs_once_per_call) {
  for (int threads : {1, 2, 3}) {
    Pool pool(threads);
    CHECK(pool.size() == threads);
    for (int call = 0; call < 2000; ++call) {
      const int n = 1 + call % 17;
      std::vector<int> hits(n, 0);
      std::atomic<int> total{0};
      pool.run(n, [&](std::int64_t t) {
        hits[t] += 1;
        total += 1;
      });
      CHECK(total.load() == n);  // the call returned after all of its tasks
      bool once = true;
      for (int h : hits) once = once && h == 1;
      CHECK(once);
    }
  }
}

// With no tasks nothing runs; with one the caller runs it.
TEST(no_task_and_one_task) {
  Pool pool(2);
  int ran = 0;
  pool.run(0, [&](std::int64_t) { ++ran; });
  CHECK(ran == 0);
  pool.run(1, [&](std::int64_t t) { ran += 1 + static_cast<int>(t); });
  CHECK(ran == 1);
  CHECK(hardware_threads() >= 1);
}

RBSIM_TEST_MAIN
