// A small persistent pool of worker threads for the step's parallel stages.
//
// run(n, f) calls f(task) for every task in [0, n), on the calling thread and the
// workers, and returns when all are done (a barrier). Each thread has its share of the
// tasks, the same contiguous run of them call after call (the caller the first), and
// takes it from the front; a thread done with its share takes what is left of another's
// from the back. So a stage's items stay, stage after stage, with the thread (and the
// core's cache) that had them, and which thread runs which task still varies with the
// schedule: a stage that uses the pool must make each task write only its own outputs (a
// range of bodies, of manifolds, a region of the solve), so that its result does not
// depend on the number of threads or on the schedule. Between calls a worker spins for
// POOL_SPIN_MICROSECONDS (the next stage usually follows within microseconds) and then
// sleeps on a futex (std::atomic::wait), so an idle pool costs no CPU.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace rbsim {

class Pool {
 public:
  // A pool of `threads` threads in all: the caller and threads - 1 workers (threads >= 1).
  explicit Pool(int threads);
  ~Pool();
  Pool(const Pool&) = delete;
  Pool& operator=(const Pool&) = delete;

  // Threads in all, the caller included.
  int size() const { return static_cast<int>(workers_.size()) + 1; }

  // The most tasks of one call (more run on the caller, in order).
  static constexpr std::int64_t MAX_TASKS = 0xffff;

  // f(task) for task in [0, n); returns when every call has returned. With one task or
  // one thread the calls run on the caller, in order.
  template <class F>
  void run(std::int64_t n, F&& f) {
    if (n <= 0) return;
    if (n == 1 || workers_.empty() || n > MAX_TASKS) {
      for (std::int64_t t = 0; t < n; ++t) f(t);
      return;
    }
    auto call = [](void* ctx, std::int64_t t) { (*static_cast<std::remove_reference_t<F>*>(ctx))(t); };
    dispatch(n, call, static_cast<void*>(&f));
  }

 private:
  using Call = void (*)(void*, std::int64_t);
  void dispatch(std::int64_t n, Call call, void* ctx);
  void work(int self);                         // worker `self`'s loop (1 .. size() - 1)
  void take_tasks(std::uint32_t g, int self);  // run call g's tasks until none is left

  // A thread's share of a call's tasks: the call's generation (high 32 bits), the share's
  // next task (16 bits) and its end (16 bits). Its owner takes tasks from the front,
  // another thread from the back; a worker that wakes late for an earlier call finds
  // another generation there and takes nothing, so a call waits only for the tasks,
  // never for a sleeping worker.
  struct alignas(64) Share {
    std::atomic<std::uint64_t> word{0};
  };

  std::vector<std::thread> workers_;
  std::vector<Share> shares_;  // one per thread, the caller's first
  Call call_ = nullptr;
  void* ctx_ = nullptr;
  std::int64_t total_ = 0;  // the call's tasks
  alignas(64) std::atomic<std::int64_t> done_{0};         // tasks of this call done
  alignas(64) std::atomic<std::uint32_t> generation_{0};  // one more per call
  std::atomic<bool> stop_{false};
};

// The machine's hardware threads (at least 1).
int hardware_threads();

// Which of one thread and `most` threads the next step runs on, from the wall times of
// the steps taken (Config::choose_threads). A step's result is the same bits on any
// number of threads, so the choice changes only the time. Most of the time the step
// runs on the last trial's faster choice: the one whose steps' median time is less (a
// step that the host held up does not decide it). A trial is 4 blocks of `block` steps,
// one thread and `most` in turn. The first begins after `first` s of stepping, the next
// 4 `first` s after it ends, and each wait is twice the last, up to `every` s (a scene
// changes most as it starts: bodies fall, then pile up), or 15 times the last trial's
// own time where that is longer (steps of a second or more: trials would be most of the
// run). Constants: THREAD_TRIAL_* (constants.hpp).
class ThreadChoice {
 public:
  ThreadChoice(int most, int block, double first, double every)
      : most_(most), block_(block), first_(first), every_(every), wait_(first) {
    for (auto& t : times_) t.reserve(2 * static_cast<std::size_t>(block));
  }

  // Threads for the next step: 1 or `most`.
  int next() {
    if (trial_ < 0 && since_ >= wait_) {  // a trial begins
      trial_ = 0;
      for (auto& t : times_) t.clear();
    }
    if (trial_ < 0) return chosen_;
    return (trial_ / block_) % 2 == 0 ? 1 : most_;
  }
  // The step that next() was asked for took `seconds` (wall time).
  void took(double seconds) {
    if (trial_ < 0) {
      since_ += seconds;
      return;
    }
    times_[(trial_ / block_) % 2].push_back(seconds);
    if (++trial_ < 4 * block_) return;
    chosen_ = median(times_[1]) < median(times_[0]) ? most_ : 1;
    ++trials_;
    trial_ = -1;
    double spent = 0.0;  // s: the trial's time
    for (const auto& t : times_)
      for (const double x : t) spent += x;
    gap_ = std::min(every_, trials_ == 1 ? 4.0 * first_ : 2.0 * gap_);
    wait_ = std::max(gap_, 15.0 * spent);
    since_ = 0.0;
  }
  // The choice of the last trial (1 before the first).
  int chosen() const { return chosen_; }
  // The trials ended so far.
  int trials() const { return trials_; }

 private:
  static double median(std::vector<double>& t) {
    const auto mid = t.begin() + static_cast<std::ptrdiff_t>(t.size() / 2);
    std::nth_element(t.begin(), mid, t.end());
    return *mid;
  }
  int most_, block_;
  double first_, every_;
  double gap_ = 0.0;    // s: the last wait between trials (before 15 times a trial's time)
  double wait_;         // s of stepping from the last trial's end to the next trial
  double since_ = 0.0;  // s of stepping since the last trial ended
  int trial_ = -1;      // the step of the trial under way (-1: none)
  std::vector<double> times_[2];  // s: the trial's steps on one thread, on `most`
  int chosen_ = 1;
  int trials_ = 0;
};

}  // namespace rbsim
