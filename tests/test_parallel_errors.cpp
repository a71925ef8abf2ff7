// core/parallel_errors.hpp: an exception thrown in an OpenMP loop's body comes out of the loop on
// the calling thread (one escaping the region would be std::terminate), later bodies skipped.
#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <string>

#include "core/parallel_errors.hpp"

namespace bgkmap {
namespace {

TEST(ParallelErrors, TheFirstExceptionOfAnOpenMpLoopIsThrownAfterItTheRestSkipped) {
  ParallelErrors errors;
  std::atomic<int> ran{0};
  // Static schedule on 4 threads: thread 2 holds iterations 500-749, fails at its first and
  // skips the other 249.
#pragma omp parallel for schedule(static) num_threads(4)
  for (int i = 0; i < 1000; ++i)
    errors.run([&] {
      if (i == 500) throw std::runtime_error("iteration 500");
      ++ran;
    });
  try {
    errors.rethrow();
    ADD_FAILURE() << "nothing thrown";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "iteration 500");
  }
  EXPECT_LE(ran.load(), 1000 - 250);
  // Thrown once: the next loop starts clean and, throwing nothing, rethrows nothing.
  ran = 0;
#pragma omp parallel for num_threads(4)
  for (int i = 0; i < 100; ++i) errors.run([&] { ++ran; });
  EXPECT_NO_THROW(errors.rethrow());
  EXPECT_EQ(ran.load(), 100);
}

TEST(ParallelErrors, OneOfSeveralFailuresIsThrownWithItsType) {
  ParallelErrors errors;
#pragma omp parallel for schedule(dynamic) num_threads(4)
  for (int i = 0; i < 64; ++i)
    errors.run([&] {
      if (i % 2) throw std::invalid_argument("odd " + std::to_string(i));
    });
  try {
    errors.rethrow();
    ADD_FAILURE() << "nothing thrown";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("odd ", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace bgkmap
