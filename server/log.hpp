// Timestamped log lines on stderr, one write per line so concurrent threads never interleave.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
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

// A bound on how many lines one source of log lines may write: a burst of `burst` lines, then
// `per_second` on average (a token bucket). Lines that do not pass are counted, and the next line
// that passes says how many were dropped, so a flood of hostile calls cannot grow the log
// without bound.
class LogRateLimit {
 public:
  LogRateLimit(double burst, double per_second)
      : burst_(burst), rate_(per_second), tokens_(burst) {}
  // True if a line may be written now; then *dropped is the number of lines refused since the
  // last one that passed.
  bool allow(std::int64_t* dropped);

 private:
  const double burst_, rate_;
  double tokens_;
  std::int64_t dropped_ = 0;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
  std::mutex mutex_;
};

// log_line through `limit`: the line, with " (N similar lines dropped)" when some were.
void log_limited(LogRateLimit& limit, LogLevel level, std::string_view message);

// `text` fit for one log field: printable ASCII without spaces ('?' for anything else), at most
// `max_bytes` (then "..."), "-" when empty.
std::string log_field(std::string_view text, std::size_t max_bytes = 200);

}  // namespace softshock::server
