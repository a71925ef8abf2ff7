#include "bgkmap/core/log.hpp"

#include <cstdio>
#include <mutex>
#include <utility>

namespace bgkmap {

namespace {
std::mutex& sink_mutex() {
  static std::mutex mutex;
  return mutex;
}
LogSink& current_sink() {
  static LogSink sink;
  return sink;
}
void write_to_stderr(LogLevel level, const std::string& text) {
  std::fprintf(stderr, "bgkmap: %s%s\n", level == LogLevel::kWarning ? "warning: " : "", text.c_str());
  std::fflush(stderr);
}
}  // namespace

void set_log_sink(LogSink sink) {
  const std::lock_guard<std::mutex> lock(sink_mutex());
  current_sink() = std::move(sink);
}

void log_message(LogLevel level, const std::string& text) {
  const std::lock_guard<std::mutex> lock(sink_mutex());
  if (current_sink()) current_sink()(level, text);
  else write_to_stderr(level, text);
}

}  // namespace bgkmap
