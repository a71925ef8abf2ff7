// The progress bar of long commands on stderr, one line per phase (reading scans, gpom's
// prediction, scoring, ...): fed by the commands' loops and by the library's ProgressCallback.
#pragma once

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

#include "bgkmap/core/progress.hpp"

namespace bgkmap {
struct ScanProgress;
}

namespace bgkmap::cli {

// A long command's -q and --progress.
struct ProgressFlags {
  bool quiet = false;
  bool force = false;
};

// Adds -q,--quiet (`quiet_help`: what it silences) and --progress to `cmd`.
void add_progress_flags(CLI::App& cmd, ProgressFlags& flags, const std::string& quiet_help);

// A ScanSource's progress as a phase counting scans.
Progress scan_progress(std::string phase, const ScanProgress& scans);

class ProgressBar {
 public:
  // Draws on a terminal unless flags.quiet: redrawn in place at most ten times a second. Into a
  // pipe or file only with flags.force (and not quiet): a line each whole percent (each second
  // when the total is not known), so logs stay short.
  explicit ProgressBar(const ProgressFlags& flags);
  ~ProgressBar() { finish(); }
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  // How far `p.phase` has come; a new phase ends the line of the one before. Thread-safe.
  void report(const Progress& p);
  // report, for the library's long phases (the bar must outlive the callback's use).
  ProgressCallback callback() {
    return [this](const Progress& p) { report(p); };
  }
  // Draws the phase's last state and ends its line; a later report starts a new line.
  void finish();

 private:
  using Clock = std::chrono::steady_clock;
  enum class Mode { kOff, kTerminal, kLines };

  void draw(Clock::time_point now);
  void end_line();

  Mode mode_;
  std::mutex mutex_;
  Progress current_, drawn_;
  bool started_ = false;  // current_ holds a phase whose line is not ended
  int last_percent_ = -1;
  Clock::time_point start_, last_draw_{};
};

}  // namespace bgkmap::cli
