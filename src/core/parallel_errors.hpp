// Carrying an exception out of an OpenMP parallel region: one that escapes a region (or one of
// its iterations) calls std::terminate, so a bad input would abort instead of ending in one line.
#pragma once

#include <atomic>
#include <exception>
#include <mutex>
#include <utility>

namespace bgkmap {

// Every iteration's body runs through run(): the first exception thrown is kept and the bodies
// after it are skipped; rethrow(), after the region, throws it on the calling thread.
//
//   ParallelErrors errors;
//   #pragma omp parallel for
//   for (int64_t i = 0; i < n; ++i)
//     errors.run([&] { ... });
//   errors.rethrow();
class ParallelErrors {
 public:
  template <class Body>
  void run(Body&& body) noexcept {
    if (failed_.load(std::memory_order_relaxed)) return;
    try {
      std::forward<Body>(body)();
    } catch (...) {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (!first_) first_ = std::current_exception();
      failed_.store(true, std::memory_order_relaxed);
    }
  }

  // Throws the kept exception, if any (call it outside the region, on the thread that began it).
  void rethrow() {
    if (!first_) return;
    std::exception_ptr e = std::move(first_);
    first_ = nullptr;
    failed_.store(false, std::memory_order_relaxed);
    std::rethrow_exception(e);
  }

 private:
  std::atomic<bool> failed_{false};
  std::mutex mutex_;
  std::exception_ptr first_;
};

}  // namespace bgkmap
