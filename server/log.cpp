#include "server/log.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <mutex>

namespace softshock::server {

void log_line(LogLevel level, std::string_view message) {
  using namespace std::chrono;
  const auto now = system_clock::now();
  const std::time_t secs = system_clock::to_time_t(now);
  const auto ms = duration_cast<milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm utc{};
  gmtime_r(&secs, &utc);
  char stamp[40];
  const std::size_t n = std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", &utc);
  std::string line(stamp, n);
  char frac[8];
  std::snprintf(frac, sizeof frac, ".%03dZ ", static_cast<int>(ms));
  line += frac;
  line += level == LogLevel::kInfo ? "I " : level == LogLevel::kWarning ? "W " : "E ";
  line += message;
  line += '\n';
  // One write(2) per line: atomic enough for a pipe or file, and no iostream locking.
  static std::mutex mutex;
  std::lock_guard lock(mutex);
  const char* p = line.data();
  std::size_t left = line.size();
  while (left > 0) {
    const ssize_t w = ::write(STDERR_FILENO, p, left);
    if (w <= 0) break;
    p += w;
    left -= static_cast<std::size_t>(w);
  }
}

bool LogRateLimit::allow(std::int64_t* dropped) {
  std::lock_guard lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  tokens_ = std::min(burst_, tokens_ + std::chrono::duration<double>(now - last_).count() * rate_);
  last_ = now;
  if (tokens_ < 1) {
    ++dropped_;
    return false;
  }
  tokens_ -= 1;
  *dropped = dropped_;
  dropped_ = 0;
  return true;
}

void log_limited(LogRateLimit& limit, LogLevel level, std::string_view message) {
  std::int64_t dropped = 0;
  if (!limit.allow(&dropped)) return;
  if (dropped == 0) {
    log_line(level, message);
  } else {
    log_line(level, std::string(message) + " (" + std::to_string(dropped) +
                        " similar line(s) dropped before this one)");
  }
}

std::string log_field(std::string_view text, std::size_t max_bytes) {
  if (text.empty()) return "-";
  std::string out;
  for (char c : text.substr(0, max_bytes)) out += (c > 0x20 && c < 0x7f) ? c : '?';
  if (text.size() > max_bytes) out += "...";
  return out;
}

}  // namespace softshock::server
