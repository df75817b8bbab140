// Timestamped log lines on stderr, one write per line so concurrent threads never interleave.
#pragma once

#include <sstream>
#include <string>
#include <string_view>

namespace softshock::server {

enum class LogLevel { kInfo, kWarning, kError };

void log_line(LogLevel level, std::string_view message);

template <typename... Args>
void log_info(const Args&... args) {
  std::ostringstream s;
  (s << ... << args);
  log_line(LogLevel::kInfo, s.str());
}

template <typename... Args>
void log_warning(const Args&... args) {
  std::ostringstream s;
  (s << ... << args);
  log_line(LogLevel::kWarning, s.str());
}

template <typename... Args>
void log_error(const Args&... args) {
  std::ostringstream s;
  (s << ... << args);
  log_line(LogLevel::kError, s.str());
}

}  // namespace softshock::server
