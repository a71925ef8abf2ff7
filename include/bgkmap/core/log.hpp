// Where the library's messages go (a device falling back mid-build, a distributed build's steps):
// one process-wide sink, the standard error by default; a program may route them elsewhere.
#pragma once

#include <functional>
#include <string>

namespace bgkmap {

enum class LogLevel { kInfo, kWarning };

// Gets a message without the "bgkmap: " prefix or a final newline (it may hold several lines).
// Called from any thread, one call at a time.
using LogSink = std::function<void(LogLevel, const std::string&)>;

// Replaces the sink; an empty one restores the default ("bgkmap: [warning: ]message" on stderr).
void set_log_sink(LogSink sink);

void log_message(LogLevel level, const std::string& text);
inline void log_info(const std::string& text) { log_message(LogLevel::kInfo, text); }
inline void log_warning(const std::string& text) { log_message(LogLevel::kWarning, text); }

}  // namespace bgkmap
