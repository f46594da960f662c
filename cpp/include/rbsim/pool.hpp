// A small persistent pool of worker threads for the step's parallel stages.
//
// run(n, f) calls f(task) for every task in [0, n), on the calling thread and the
// workers, and returns when all are done (a barrier). Tasks are taken from a shared
// counter, so which thread runs which task varies from call to call: a stage that uses
// the pool must make each task write only its own outputs (a range of bodies, of
// manifolds, a region of the solve), so that its result does not depend on the number of
// threads or on the schedule. Between calls a worker spins for POOL_SPIN_MICROSECONDS
// (the next stage usually follows within microseconds) and then sleeps on a futex
// (std::atomic::wait), so an idle pool costs no CPU.
#pragma once

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
  void work();                      // a worker's loop
  void take_tasks(std::uint32_t g);  // run call g's tasks until none is left

  std::vector<std::thread> workers_;
  Call call_ = nullptr;
  void* ctx_ = nullptr;
  // the call's generation (high 32 bits), its next task (16 bits) and its task count (16
  // bits): a worker that wakes late for an earlier call finds another generation there
  // and takes nothing, so a call waits only for the tasks, never for a sleeping worker
  alignas(64) std::atomic<std::uint64_t> next_{0};
  alignas(64) std::atomic<std::int64_t> done_{0};         // tasks of this call done
  alignas(64) std::atomic<std::uint32_t> generation_{0};  // one more per call
  std::atomic<bool> stop_{false};
};

// The machine's hardware threads (at least 1).
int hardware_threads();

}  // namespace rbsim
