// Counts the items of a long phase, maybe from the threads of a parallel loop, and reports them to
// a ProgressCallback from one thread at a time, about a thousand times a phase at most.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <utility>

#include "bgkmap/core/progress.hpp"

namespace bgkmap {

class ProgressCounter {
 public:
  // An empty callback makes every call a no-op. The first report (0 done) is made here.
  ProgressCounter(ProgressCallback callback, std::string phase, std::string unit, uint64_t total)
      : callback_(std::move(callback)), progress_{std::move(phase), std::move(unit), 0, total, false},
        stride_(std::max<uint64_t>(1, total / 1000)) {
    if (callback_) callback_(progress_);
  }

  // `n` more items done; thread-safe. A thread that finds another reporting does not wait for it.
  void add(uint64_t n = 1) {
    if (!callback_) return;
    const uint64_t done = done_.fetch_add(n, std::memory_order_relaxed) + n;
    if (done / stride_ == (done - n) / stride_) return;  // reported at most once a stride
    std::unique_lock<std::mutex> lock(reporting_, std::try_to_lock);
    if (!lock.owns_lock()) return;
    progress_.done = std::min(done_.load(std::memory_order_relaxed), progress_.total ? progress_.total : done);
    callback_(progress_);
  }

  // Reports the whole phase done (call it on the thread that made the counter, after the loop).
  void finish() {
    if (!callback_) return;
    const std::lock_guard<std::mutex> lock(reporting_);
    progress_.done = progress_.total ? progress_.total : done_.load();
    callback_(progress_);
  }

 private:
  ProgressCallback callback_;
  Progress progress_;
  uint64_t stride_;
  std::atomic<uint64_t> done_{0};
  std::mutex reporting_;
};

}  // namespace bgkmap
