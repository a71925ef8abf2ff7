// A one-line progress bar on stderr for long commands (build, simulate). It draws only when
// stderr is a terminal, so logs and pipes stay clean, and redraws at most ten times a second.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

namespace bgkmap::cli {

class ProgressBar {
 public:
  // enabled = false (e.g. --quiet) draws nothing, like a non-terminal stderr.
  ProgressBar(std::string label, uint64_t total, bool enabled = true)
      : label_(std::move(label)), total_(total), active_(enabled && ::isatty(::fileno(stderr)) == 1),
        start_(Clock::now()) {}
  ~ProgressBar() { finish(); }
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  // `done` items out of total (capped at total).
  void update(uint64_t done) {
    done_ = std::min(done, total_);
    const auto now = Clock::now();
    if (!active_ || (now - last_draw_ < std::chrono::milliseconds(100) && done_ < total_)) return;
    last_draw_ = now;
    draw(now);
  }

  // Draws the final state and ends the line; later calls do nothing.
  void finish() {
    if (!active_) return;
    draw(Clock::now());
    std::fputc('\n', stderr);
    active_ = false;
  }

 private:
  using Clock = std::chrono::steady_clock;

  void draw(Clock::time_point now) const {
    constexpr int kWidth = 30;
    const double fraction = total_ ? static_cast<double>(done_) / static_cast<double>(total_) : 1.0;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const int filled = static_cast<int>(fraction * kWidth);
    std::string bar(filled, '#');
    bar.resize(kWidth, '.');
    char eta[32] = "";
    if (done_ > 0 && done_ < total_)
      std::snprintf(eta, sizeof eta, ", %.0f s left", elapsed * (1.0 - fraction) / fraction);
    std::fprintf(stderr, "\r%s [%s] %llu/%llu (%3.0f%%) %.0f s%s   ", label_.c_str(), bar.c_str(),
                 static_cast<unsigned long long>(done_), static_cast<unsigned long long>(total_), 100 * fraction,
                 elapsed, eta);
    std::fflush(stderr);
  }

  std::string label_;
  uint64_t total_;
  uint64_t done_ = 0;
  bool active_;
  Clock::time_point start_, last_draw_{};
};

}  // namespace bgkmap::cli
