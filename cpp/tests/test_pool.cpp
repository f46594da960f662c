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

// ThreadChoice: before its first trial the steps run on one thread; a trial alternates
// blocks of one thread and of all, and the faster wins until the next trial, which
// begins once `every` seconds of stepping have passed since the last ended.
namespace {
// Steps of `one` and `most` seconds (one thread, all) from the choice `c`: n steps; the
// threads of each step in `seen` (appended).
void run_steps(ThreadChoice& c, int n, double one, double most, std::vector<int>& seen) {
  for (int k = 0; k < n; ++k) {
    const int t = c.next();
    seen.push_back(t);
    c.took(t == 1 ? one : most);
  }
}
}  // namespace

TEST(thread_choice_takes_the_faster) {
  // (times in powers of two, so that the sums are exact)
  // block 2; the first trial after 0.125 s, the next 0.5 s after it, then 1 s (the cap)
  ThreadChoice c(2, 2, 0.125, 1.0);
  const double fast = 1.0 / 512, slow = 1.0 / 256;  // s a step
  std::vector<int> seen;
  run_steps(c, 32, slow, fast, seen);  // 0.125 s on one thread: the trial starts after
  CHECK(c.chosen() == 1);
  for (int t : seen) CHECK(t == 1);
  seen.clear();
  run_steps(c, 8, slow, fast, seen);  // the trial: 1 1 2 2 1 1 2 2, two threads faster
  const std::vector<int> trial = {1, 1, 2, 2, 1, 1, 2, 2};
  CHECK(seen == trial);
  CHECK(c.chosen() == 2);
  seen.clear();
  run_steps(c, 256, slow, fast, seen);  // 0.5 s on two threads, no trial within it
  for (int t : seen) CHECK(t == 2);
  seen.clear();
  run_steps(c, 8, fast, slow, seen);  // the next trial: now one thread is faster
  CHECK(seen == trial);
  CHECK(c.chosen() == 1);
  CHECK(c.trials() == 2);
  seen.clear();
  run_steps(c, 512, fast, slow, seen);  // 1 s (twice 0.5, the cap) on one thread
  for (int t : seen) CHECK(t == 1);
  CHECK(c.trials() == 2);
  seen.clear();
  run_steps(c, 8, fast, slow, seen);
  CHECK(seen == trial);
  CHECK(c.trials() == 3);
  // steps of 0.25 s: a trial takes 2 s (block 2), and the next waits 15 times that, 30 s
  ThreadChoice long_steps(2, 2, 0.0, 1.0);
  seen.clear();
  run_steps(long_steps, 8, 0.25, 0.25, seen);
  CHECK(long_steps.trials() == 1);
  seen.clear();
  run_steps(long_steps, 120, 0.25, 0.25, seen);  // 30 s on one thread
  CHECK(long_steps.trials() == 1);
  for (int t : seen) CHECK(t == 1);
  run_steps(long_steps, 8, 0.25, 0.25, seen);  // the next trial
  CHECK(long_steps.trials() == 2);
  // one step the host held up does not decide a trial: two threads' steps take half of
  // one thread's but one of them 40 times longer (their sum the larger), and two win
  ThreadChoice held(2, 2, 0.0, 1.0);
  for (int k = 0; k < 8; ++k) {
    const int t = held.next();
    held.took(t == 1 ? 1.0 / 64 : (k == 2 ? 40.0 / 128 : 1.0 / 128));
  }
  CHECK(held.trials() == 1);
  CHECK(held.chosen() == 2);
  // a trial of equal times keeps one thread (no gain for the hand-offs)
  ThreadChoice same(3, 1, 0.0, 1.0);
  seen.clear();
  run_steps(same, 4, 0.25, 0.25, seen);
  const std::vector<int> short_trial = {1, 3, 1, 3};
  CHECK(seen == short_trial);
  CHECK(same.chosen() == 1);
}

RBSIM_TEST_MAIN
