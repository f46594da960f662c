// The worker pool (rbsim/pool.hpp): a generation counter that a call advances and the
// workers wait on, one atomic word with the call's generation and its next task, and a
// count of the tasks done that the caller waits on.
#include "rbsim/pool.hpp"

#include <chrono>

#include "rbsim/constants.hpp"

namespace rbsim {

namespace {

// A hint to the processor that this is a spin-wait loop.
inline void relax_cpu() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#else
  std::this_thread::yield();
#endif
}

}  // namespace

Pool::Pool(int threads) {
  for (int k = 1; k < threads; ++k) workers_.emplace_back([this] { work(); });
}

Pool::~Pool() {
  stop_.store(true, std::memory_order_release);
  generation_.fetch_add(1, std::memory_order_acq_rel);
  generation_.notify_all();
  for (auto& t : workers_) t.join();
}

void Pool::take_tasks(std::uint32_t g) {
  std::uint64_t v = next_.load(std::memory_order_acquire);
  for (;;) {
    const std::uint64_t task = (v >> 16) & 0xffff, n = v & 0xffff;
    if ((v >> 32) != g || task >= n) return;
    if (!next_.compare_exchange_weak(v, v + (std::uint64_t{1} << 16), std::memory_order_acq_rel,
                                     std::memory_order_acquire))
      continue;  // (v reloaded)
    // the task is this call's and not done: the call's fields stay until it is
    call_(ctx_, static_cast<std::int64_t>(task));
    if (done_.fetch_add(1, std::memory_order_acq_rel) + 1 == static_cast<std::int64_t>(n))
      done_.notify_all();
    v = next_.load(std::memory_order_acquire);
  }
}

void Pool::dispatch(std::int64_t n, Call call, void* ctx) {
  using clock = std::chrono::steady_clock;
  call_ = call;
  ctx_ = ctx;
  done_.store(0, std::memory_order_relaxed);
  const std::uint32_t g = generation_.load(std::memory_order_relaxed) + 1;
  next_.store((std::uint64_t{g} << 32) | static_cast<std::uint64_t>(n), std::memory_order_release);
  generation_.store(g, std::memory_order_release);
  generation_.notify_all();
  take_tasks(g);
  // the tasks the workers took: spin a little, then sleep until the last one is done
  const auto until = clock::now() + std::chrono::microseconds(constants::POOL_SPIN_MICROSECONDS);
  for (int k = 0;; ++k) {
    const std::int64_t d = done_.load(std::memory_order_acquire);
    if (d == n) return;
    relax_cpu();
    if ((k & 63) == 63 && clock::now() > until) done_.wait(d, std::memory_order_acquire);
  }
}

void Pool::work() {
  using clock = std::chrono::steady_clock;
  const auto spin = std::chrono::microseconds(constants::POOL_SPIN_MICROSECONDS);
  std::uint32_t seen = 0;  // (the generation at the pool's making)
  for (;;) {
    // spin a little (the next stage is usually microseconds away), then sleep
    const auto until = clock::now() + spin;
    std::uint32_t now = generation_.load(std::memory_order_acquire);
    for (int k = 0; now == seen; ++k) {
      relax_cpu();
      if ((k & 63) == 63 && clock::now() > until) generation_.wait(seen, std::memory_order_acquire);
      now = generation_.load(std::memory_order_acquire);
    }
    seen = now;
    if (stop_.load(std::memory_order_acquire)) return;
    take_tasks(now);
  }
}

int hardware_threads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

}  // namespace rbsim
