#include "cli/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <utility>

#include "bgkmap/io/scan_source.hpp"

namespace bgkmap::cli {

void add_progress_flags(CLI::App& cmd, ProgressFlags& flags, const std::string& quiet_help) {
  cmd.add_flag("-q,--quiet", flags.quiet, quiet_help);
  cmd.add_flag("--progress", flags.force,
               "Show the progress bar even when stderr is not a terminal (a line each percent); by default it "
               "shows only on a terminal");
}

Progress scan_progress(std::string phase, const ScanProgress& scans) {
  return {std::move(phase), "scans", scans.done, scans.total, scans.estimated};
}

ProgressBar::ProgressBar(const ProgressFlags& flags)
    : mode_(flags.quiet                              ? Mode::kOff
            : ::isatty(::fileno(stderr)) == 1        ? Mode::kTerminal
            : flags.force                            ? Mode::kLines
                                                     : Mode::kOff) {}

void ProgressBar::report(const Progress& p) {
  if (mode_ == Mode::kOff) return;
  const std::lock_guard<std::mutex> lock(mutex_);
  const auto now = Clock::now();
  if (started_ && p.phase != current_.phase) end_line();
  if (!started_) {
    started_ = true;
    start_ = now;
    last_percent_ = -1;
    last_draw_ = {};
  }
  current_ = p;
  if (current_.total > 0) current_.done = std::min(current_.done, current_.total);
  const bool complete = current_.total > 0 && current_.done == current_.total;
  if (mode_ == Mode::kTerminal) {
    if (now - last_draw_ >= std::chrono::milliseconds(100) || complete) draw(now);
  } else if (current_.total > 0) {
    const int percent = static_cast<int>(100 * current_.done / current_.total);
    if (percent > last_percent_) draw(now);
  } else if (now - last_draw_ >= std::chrono::seconds(1)) {
    draw(now);
  }
}

void ProgressBar::finish() {
  if (mode_ == Mode::kOff) return;
  const std::lock_guard<std::mutex> lock(mutex_);
  if (started_) end_line();
}

void ProgressBar::end_line() {
  if (mode_ == Mode::kTerminal || current_.done != drawn_.done || current_.total != drawn_.total ||
      current_.estimated != drawn_.estimated)
    draw(Clock::now());
  if (mode_ == Mode::kTerminal) std::fputc('\n', stderr);
  std::fflush(stderr);
  started_ = false;
}

void ProgressBar::draw(Clock::time_point now) {
  last_draw_ = now;
  drawn_ = current_;
  const Progress& p = current_;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  std::string text = p.phase;
  if (p.total > 0) {
    constexpr int kWidth = 30;
    const double fraction = static_cast<double>(p.done) / static_cast<double>(p.total);
    last_percent_ = static_cast<int>(100 * p.done / p.total);
    std::string bar(static_cast<size_t>(fraction * kWidth), '#');
    bar.resize(kWidth, '.');
    char counts[160];
    std::snprintf(counts, sizeof counts, " [%s] %llu/%s%llu %s (%d%%) %.0f s", bar.c_str(),
                  static_cast<unsigned long long>(p.done), p.estimated ? "~" : "",
                  static_cast<unsigned long long>(p.total), p.unit.c_str(), last_percent_, elapsed);
    text += counts;
    if (p.done > 0 && p.done < p.total) {
      char eta[48];
      std::snprintf(eta, sizeof eta, ", %.0f s left", elapsed * (1.0 - fraction) / fraction);
      text += eta;
    }
  } else {
    char counts[96];
    std::snprintf(counts, sizeof counts, " %llu %s %.0f s", static_cast<unsigned long long>(p.done), p.unit.c_str(),
                  elapsed);
    text += counts;
  }
  if (mode_ == Mode::kTerminal) std::fprintf(stderr, "\r%s   ", text.c_str());
  else std::fprintf(stderr, "%s\n", text.c_str());
  std::fflush(stderr);
}

}  // namespace bgkmap::cli
