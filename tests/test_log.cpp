// The library's messages: to the sink a program sets, else "bgkmap: ..." lines on stderr.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "bgkmap/core/log.hpp"

namespace bgkmap {
namespace {

TEST(Log, GoesToTheSinkSetAndBackToStderrWhenCleared) {
  std::vector<std::pair<LogLevel, std::string>> seen;
  set_log_sink([&](LogLevel level, const std::string& text) { seen.emplace_back(level, text); });
  testing::internal::CaptureStderr();
  log_warning("OpenCL device 'x' failed");
  log_info("resuming\n  rank 0: scan 3");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].first, LogLevel::kWarning);
  EXPECT_EQ(seen[0].second, "OpenCL device 'x' failed");
  EXPECT_EQ(seen[1].first, LogLevel::kInfo);
  EXPECT_EQ(seen[1].second, "resuming\n  rank 0: scan 3");

  set_log_sink(nullptr);
  testing::internal::CaptureStderr();
  log_warning("w");
  log_info("i");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "bgkmap: warning: w\nbgkmap: i\n");
  EXPECT_EQ(seen.size(), 2u);
}

}  // namespace
}  // namespace bgkmap
