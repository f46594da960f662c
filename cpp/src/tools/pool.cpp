// The worker pool (rbsim/pool.hpp): a generation counter that a call advances and the
// workers wait on, one atomic word per thread with the call's generation and that
// thread's share of the tasks, and a count of the tasks done that the caller waits on.
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

Pool::Pool(int threads) : shares_(static_cast<std::size_t>(threads < 1 ? 1 : threads)) {
  for (int k = 1; k < threads; ++k) workers_.emplace_back([this, k] { work(k); });
}

Pool::~Pool() {
  stop_.store(true, std::memory_order_release);
  generation_.fetch_add(1, std::memory_order_acq_rel);
  generation_.notify_all();
  for (auto& t : workers_) t.join();
}

void Pool::take_tasks(std::uint32_t g, int self) {
  const int n_shares = static_cast<int>(shares_.size());
  // its own share from the front, then the others' from the back, the next thread's first
  for (int k = 0; k < n_shares; ++k) {
    const bool own = k == 0;
    std::atomic<std::uint64_t>& word = shares_[(self + k) % n_shares].word;
    std::uint64_t v = word.load(std::memory_order_acquire);
    for (;;) {
      const std::uint64_t next = (v >> 16) & 0xffff, end = v & 0xffff;
      if ((v >> 32) != g) return;  // a later call has begun: this one's tasks are all taken
      if (next >= end) break;
      const std::uint64_t taken = own ? v + (std::uint64_t{1} << 16) : v - 1;
      if (!word.compare_exchange_weak(v, taken, std::memory_order_acq_rel,
                                      std::memory_order_acquire))
        continue;  // (v reloaded)
      // the task is this call's and not done: the call's fields stay until it is
      call_(ctx_, static_cast<std::int64_t>(own ? next : end - 1));
      if (done_.fetch_add(1, std::memory_order_acq_rel) + 1 == total_) done_.notify_all();
      v = word.load(std::memory_order_acquire);
    }
  }
}

void Pool::dispatch(std::int64_t n, Call call, void* ctx) {
  using clock = std::chrono::steady_clock;
  call_ = call;
  ctx_ = ctx;
  total_ = n;
  done_.store(0, std::memory_order_relaxed);
  const std::uint32_t g = generation_.load(std::memory_order_relaxed) + 1;
  const std::int64_t n_shares = static_cast<std::int64_t>(shares_.size());
  for (std::int64_t s = 0; s < n_shares; ++s) {
    const auto first = static_cast<std::uint64_t>(n * s / n_shares);
    const auto end = static_cast<std::uint64_t>(n * (s + 1) / n_shares);
    shares_[s].word.store((std::uint64_t{g} << 32) | (first << 16) | end,
                          std::memory_order_release);
  }
  generation_.store(g, std::memory_order_release);
  generation_.notify_all();
  take_tasks(g, 0);
  // the tasks the workers took: spin a little, then sleep until the last one is done
  const auto until = clock::now() + std::chrono::microseconds(constants::POOL_SPIN_MICROSECONDS);
  for (int k = 0;; ++k) {
    const std::int64_t d = done_.load(std::memory_order_acquire);
    if (d == n) return;
    relax_cpu();
    if ((k & 63) == 63 && clock::now() > until) done_.wait(d, std::memory_order_acquire);
  }
}

void Pool::work(int self) {
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
    take_tasks(now, self);
  }
}

int hardware_threads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

}  // namespace rbsim
